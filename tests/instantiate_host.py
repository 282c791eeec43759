"""An FMI 2 or FMI 3 co-simulation importer reduced to one instantiation, standard library only (ctypes), so that any
CPython 3 can run it (the loader's tests of host processes with older Pythons):

    python instantiate_host.py FOLDER

FOLDER is the extracted FMU. Prints each message the FMU logs as "log STATUS TEXT", then "instance made" or
"instance NULL"; a crash shows as the exit status.
"""

import ctypes
import re
import sys
from pathlib import Path

folder = Path(sys.argv[1]).resolve()
description = (folder / "modelDescription.xml").read_text(encoding="utf-8")
fmi = 3 if 'fmiVersion="3' in description else 2
token = re.search(r'(?:guid|instantiationToken)="([^"]*)"', description).group(1).encode()
model = re.search(r'modelIdentifier="([^"]*)"', description).group(1)
library = ctypes.CDLL(str(folder / "binaries" / ("linux64" if fmi == 2 else "x86_64-linux") / (model + ".so")))


def say(text):
    print(text, flush=True)


if fmi == 2:
    # the loader passes every message as format "%s" and the text, which arrives as the first variadic argument
    LOGGER = ctypes.CFUNCTYPE(None, ctypes.c_void_p, ctypes.c_char_p, ctypes.c_int, ctypes.c_char_p, ctypes.c_char_p,
                              ctypes.c_char_p)
    log = LOGGER(lambda env, name, status, category, message, text: say(
        "log {} {}".format(status, (text if message == b"%s" else message).decode(errors="replace"))))

    class Callbacks(ctypes.Structure):
        _fields_ = [("logger", LOGGER), ("allocateMemory", ctypes.c_void_p), ("freeMemory", ctypes.c_void_p),
                    ("stepFinished", ctypes.c_void_p), ("componentEnvironment", ctypes.c_void_p)]

    callbacks = Callbacks(log, None, None, None, None)
    instantiate = library.fmi2Instantiate
    instantiate.restype = ctypes.c_void_p
    instantiate.argtypes = (ctypes.c_char_p, ctypes.c_int, ctypes.c_char_p, ctypes.c_char_p, ctypes.c_void_p,
                            ctypes.c_int, ctypes.c_int)
    instance = instantiate(b"probe", 1, token, (folder / "resources").as_uri().encode(), ctypes.byref(callbacks), 0, 0)
else:
    LOGGER = ctypes.CFUNCTYPE(None, ctypes.c_void_p, ctypes.c_int, ctypes.c_char_p, ctypes.c_char_p)
    log = LOGGER(lambda env, status, category, message: say(
        "log {} {}".format(status, message.decode(errors="replace"))))
    instantiate = library.fmi3InstantiateCoSimulation
    instantiate.restype = ctypes.c_void_p
    instantiate.argtypes = (ctypes.c_char_p, ctypes.c_char_p, ctypes.c_char_p, ctypes.c_bool, ctypes.c_bool,
                            ctypes.c_bool, ctypes.c_bool, ctypes.c_void_p, ctypes.c_size_t, ctypes.c_void_p, LOGGER,
                            ctypes.c_void_p)
    instance = instantiate(b"probe", token, (str(folder / "resources") + "/").encode(), False, False, False, False,
                           None, 0, None, log, None)
say("instance " + ("made" if instance else "NULL"))
