"""A slave offers itself to its FMU's C loader (``src/stickslip/fmu/loader/fast_path.h``), which then calls the
slave's methods directly: the block's steps and output reads (the fast path), and the input and output derivatives
that the FMI libraries lack. No imports beyond the standard library: the block's FMUs bundle this module in their
runtime package, the coupling FMU beside its slave.
"""

import ctypes
import os


def offer_to_loader(slave, resources, platform, first_output, output_kinds):
    """Offer ``slave`` to the C loader that is instantiating it: ``binaries/<platform>/<slave's class name>.so``
    beside the ``resources`` folder, with the value reference of its first output and its outputs' kinds ("r"
    real, "i" integer, one letter per output). Nothing happens where that library is not loaded in this process (a
    slave made in Python, the builder) or cannot bind."""
    if resources is None or not hasattr(os, "RTLD_NOLOAD"):
        return
    folder = os.path.dirname(os.path.abspath(resources))
    path = os.path.join(folder, "binaries", platform, f"{type(slave).__name__}.so")
    try:
        loader = ctypes.PyDLL(path, mode=os.RTLD_NOLOAD | os.RTLD_LOCAL)  # the GIL stays held in the call
    except OSError:
        return
    try:
        bind = getattr(loader, "sbf_bind_slave", None)
        if bind is not None:
            bind.argtypes, bind.restype = (ctypes.py_object, ctypes.c_uint, ctypes.c_char_p), ctypes.c_int
            bind(slave, first_output, output_kinds.encode("ascii"))
            take_resources_folder(slave, loader)
    finally:
        # the reference this lookup took; the host holds its own
        ctypes.CDLL(None).dlclose(ctypes.c_void_p(loader._handle))


def take_resources_folder(slave, loader):
    """``slave.resources`` set to the resources folder as the host named it, which the loader knows: the FMI
    library may have been handed another path to the same folder (one it does not rewrite, see the loader's
    ``inner_library_path``)."""
    folder = getattr(loader, "sbf_bound_folder", None)
    if folder is None:
        return
    folder.argtypes, folder.restype = (), ctypes.c_char_p
    named = folder()
    if named:
        slave.resources = os.fsdecode(named)
