"""A plain FMI 2.0 co-simulation importer in Python, through ctypes, as Python tools other than FMPy load an FMU's
binary: the Windows tests run it in python.org's embeddable CPython under Wine, so that the FMU finds a Python already
in its host process. Standard library only (the embeddable CPython has nothing else). Command line, modes and output
are those of the C host (``src/stickslip/hosts/c_host/host.c``), whose parser (``run_host``) reads them:

    python fmi2_ctypes_host.py BINARY RESOURCE_URI GUID MODE STOP STEP OUTPUT_VR [rVR=VALUE | iVR=VALUE ...]

MODE run (one instance: "x T X" at every communication point), bad ("status exit CODE" of
fmi2ExitInitializationMode with every setting, the last one invalid; then a new instance without it, "x" lines), ramp
(``$HOST_RAMP`` "VR RATE": "status ramp CODE" of fmi2SetRealInputDerivatives of order 1, then "x" lines). Every
logged message is printed as "log STATUS INSTANCE TEXT"; logging is on with ``$HOST_LOGGING=1``. A failing call ends
the program with "failed FUNCTION STATUS" and exit code 1; "done" and 0 at the end.
"""

import ctypes
import os
import sys

VR = ctypes.c_uint
#: fmi2CallbackLogger: the loader passes every message as format "%s" and the text
LOGGER = ctypes.CFUNCTYPE(None, ctypes.c_void_p, ctypes.c_char_p, ctypes.c_int, ctypes.c_char_p, ctypes.c_char_p,
                          ctypes.c_char_p)


class Callbacks(ctypes.Structure):
    _fields_ = [("logger", LOGGER), ("allocateMemory", ctypes.c_void_p), ("freeMemory", ctypes.c_void_p),
                ("stepFinished", ctypes.c_void_p), ("componentEnvironment", ctypes.c_void_p)]


def say(text):
    print(text, flush=True)


@LOGGER
def logger(environment, name, status, category, message, text):
    shown = text if message == b"%s" else message
    say(f"log {status} {name.decode()} {shown.decode(errors='replace').replace(chr(10), ' ')}")


def check(function, status):
    if status > 1:
        say(f"failed {function} {status}")
        sys.exit(1)


class Host:
    """The FMU's binary and the run's settings from the command line."""

    def __init__(self, argv):
        binary, self.resources, self.guid, self.mode, stop, step, output, *settings = argv
        self.fmu = ctypes.CDLL(binary)
        self.stop, self.step, self.output = float(stop), float(step), VR(int(output))
        self.settings = [(setting[0], int(setting[1:].split("=")[0]), setting.split("=", 1)[1]) for setting in settings]
        self.fmu.fmi2Instantiate.restype = ctypes.c_void_p
        self.fmu.fmi2Instantiate.argtypes = (ctypes.c_char_p, ctypes.c_int, ctypes.c_char_p, ctypes.c_char_p,
                                             ctypes.POINTER(Callbacks), ctypes.c_int, ctypes.c_int)
        self.fmu.fmi2SetupExperiment.argtypes = (ctypes.c_void_p, ctypes.c_int, ctypes.c_double, ctypes.c_double,
                                                 ctypes.c_int, ctypes.c_double)
        self.fmu.fmi2DoStep.argtypes = (ctypes.c_void_p, ctypes.c_double, ctypes.c_double, ctypes.c_int)
        for name in ("fmi2FreeInstance", "fmi2EnterInitializationMode", "fmi2ExitInitializationMode",
                     "fmi2Terminate"):
            getattr(self.fmu, name).argtypes = (ctypes.c_void_p,)
        c_runtime = ctypes.CDLL("msvcrt" if os.name == "nt" else None)
        self.callbacks = Callbacks(logger, ctypes.cast(c_runtime.calloc, ctypes.c_void_p),
                                   ctypes.cast(c_runtime.free, ctypes.c_void_p), None, None)

    def instantiate(self, name):
        instance = self.fmu.fmi2Instantiate(name.encode(), 1, self.guid.encode(), self.resources.encode(),
                                            ctypes.byref(self.callbacks), 0, os.environ.get("HOST_LOGGING") == "1")
        if not instance:
            say("failed fmi2Instantiate NULL")
            sys.exit(1)
        return ctypes.c_void_p(instance)

    def initialize(self, instance, settings):
        check("fmi2SetupExperiment", self.fmu.fmi2SetupExperiment(instance, 0, 0.0, 0.0, 1, self.stop))
        for kind, reference, value in settings:
            setter, value = (("fmi2SetInteger", ctypes.c_int(int(value))) if kind == "i" else
                             ("fmi2SetReal", ctypes.c_double(float(value))))
            check(setter, getattr(self.fmu, setter)(instance, ctypes.byref(VR(reference)), 1, ctypes.byref(value)))
        check("fmi2EnterInitializationMode", self.fmu.fmi2EnterInitializationMode(instance))
        return self.fmu.fmi2ExitInitializationMode(instance)

    def output_value(self, instance):
        value = ctypes.c_double()
        check("fmi2GetReal", self.fmu.fmi2GetReal(instance, ctypes.byref(self.output), 1, ctypes.byref(value)))
        return value.value

    def run_initialized(self, instance):
        """Step to the stop time at FMPy's communication points, printing "x T X" at each; then free it."""
        t, n = 0.0, 0
        say(f"x {t!r} {self.output_value(instance)!r}")
        while not (t > self.stop or abs(t - self.stop) <= 1e-9 * max(abs(t), abs(self.stop))):
            after = (n + 1) * self.step
            after = self.stop if after > self.stop and abs(after - self.stop) > 1e-9 * after else after
            check("fmi2DoStep", self.fmu.fmi2DoStep(instance, t, after - t, 1))
            t, n = after, n + 1
            say(f"x {t!r} {self.output_value(instance)!r}")
        check("fmi2Terminate", self.fmu.fmi2Terminate(instance))
        self.fmu.fmi2FreeInstance(instance)

    def run(self):
        if self.mode == "bad":
            instance = self.instantiate("bad")
            say(f"status exit {self.initialize(instance, self.settings)}")
            self.fmu.fmi2FreeInstance(instance)
            self.settings.pop()
        instance = self.instantiate("ramp" if self.mode == "ramp" else "run")
        check("fmi2ExitInitializationMode", self.initialize(instance, self.settings))
        if self.mode == "ramp":
            reference, rate = os.environ["HOST_RAMP"].split()
            status = self.fmu.fmi2SetRealInputDerivatives(instance, ctypes.byref(VR(int(reference))), 1,
                                                          ctypes.byref(ctypes.c_int(1)),
                                                          ctypes.byref(ctypes.c_double(float(rate))))
            say(f"status ramp {status}")
        self.run_initialized(instance)
        say("done")


if __name__ == "__main__":
    Host(sys.argv[1:]).run()
