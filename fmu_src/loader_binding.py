"""What every slave does for the FMU's binaries, the C loader (``src/stickslip/fmu/loader``) in front of the FMI
library's binary (PythonFMU's or pythonfmu3's). No imports beyond the standard library: the block's FMUs bundle
this module in their runtime package, the coupling FMU in its own.

- :func:`offer_to_loader`: the slave offers itself to the loader, which then calls the slave's methods directly:
  the block's steps and output reads (the fast path), and the input and output derivatives that the FMI libraries
  lack.
- :func:`balance_release`: an exception of the slave leaves it usable, so that the loader (built with
  ``slave_survives_release``) reports the call's failure as an error status and the instance goes on.
- :func:`serialized_states`: FMU states as bytes (a header that says whose state they hold, then the slave's
  fields); bytes that are no FMU state of the slave are refused with the reason, never with an exception; the loader
  looks for :data:`REFUSED_STATE`.
- :func:`hold_loader_namespace`: the module PythonFMU loads the slave from keeps its globals.
"""

import ctypes
import functools
import os
import struct
import zlib

#: The methods PythonFMU's C++ wrapper calls on an FMI 2 slave (``PyObject_CallMethod(pInstance_, ...)`` in its
#: PySlaveInstance.cpp): the entry points :func:`balance_release` wraps.
PYTHONFMU_ENTRY_POINTS = (
    "setup_experiment", "enter_initialization_mode", "exit_initialization_mode", "do_step", "terminate",
    "get_real", "get_integer", "get_boolean", "get_string", "set_real", "set_integer", "set_boolean", "set_string",
    "_get_fmu_state", "_set_fmu_state",
)


#: FMI version: {os.name: (the FMU's folder of this system's binaries, their file suffix)}
BINARY_FOLDERS = {2: {"posix": ("linux64", ".so"), "nt": ("win64", ".dll")},
                  3: {"posix": ("x86_64-linux", ".so"), "nt": ("x86_64-windows", ".dll")}}


def offer_to_loader(slave, resources, fmi_version, first_output, output_kinds):
    """Offer ``slave`` to the C loader that is instantiating it: ``binaries/<folder>/<slave's class name><suffix>``
    beside the ``resources`` folder (:data:`BINARY_FOLDERS` of the FMI version ``fmi_version``), with the value
    reference of its first output and its outputs' kinds ("r" real, "i" integer, one letter per output). Nothing
    happens where that library is not loaded in this process (a slave made in Python, the builder) or cannot bind."""
    if resources is None or os.name not in BINARY_FOLDERS[fmi_version]:
        return
    platform, suffix = BINARY_FOLDERS[fmi_version][os.name]
    folder = os.path.dirname(os.path.abspath(resources))
    loader = _loaded_library(os.path.join(folder, "binaries", platform, f"{type(slave).__name__}{suffix}"))
    if loader is None:
        return
    try:
        bind = getattr(loader, "sbf_bind_slave", None)
        if bind is not None:
            bind.argtypes, bind.restype = (ctypes.py_object, ctypes.c_uint, ctypes.c_char_p), ctypes.c_int
            bind(slave, first_output, output_kinds.encode("ascii"))
            take_resources_folder(slave, loader)
    finally:
        if os.name == "posix":  # the reference this lookup took; the host holds its own
            ctypes.CDLL(None).dlclose(ctypes.c_void_p(loader._handle))


def _loaded_library(path):
    """The library at ``path`` if this process has loaded it (``ctypes.PyDLL``: the GIL stays held in its calls),
    else None. POSIX: a reference is taken (dlclose it); Windows: none is."""
    if os.name == "nt":  # by its long path: the FMI library may have been handed a short (8.3) one
        kernel32 = ctypes.WinDLL("kernel32", use_last_error=True)
        kernel32.GetModuleHandleW.argtypes, kernel32.GetModuleHandleW.restype = (ctypes.c_wchar_p,), ctypes.c_void_p
        long_path = ctypes.create_unicode_buffer(32768)
        if kernel32.GetLongPathNameW(path, long_path, len(long_path)):
            path = long_path.value
        handle = kernel32.GetModuleHandleW(path)
        return ctypes.PyDLL(path, handle=handle) if handle else None
    try:
        return ctypes.PyDLL(path, mode=os.RTLD_NOLOAD | os.RTLD_LOCAL)
    except OSError:
        return None


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


# ---- the library's release of the slave on an exception ------------------------------------------------------


def balance_release(cls, entry_points):
    """Wrap the methods ``entry_points`` of ``cls`` with :func:`_survives_release`.

    ``entry_points``: the methods the library's C++ wrapper calls on the slave (:data:`PYTHONFMU_ENTRY_POINTS`
    for PythonFMU). Not covered: the static ``_fmu_state_to_bytes``/``_fmu_state_from_bytes``, called on the class;
    they must not raise (:func:`serialized_states`).
    """
    for name in entry_points:
        setattr(cls, name, _survives_release(getattr(cls, name)))


def _survives_release(method):
    """``method``, which on an exception first takes the references that the wrapper will drop once too often.

    PythonFMU 0.7.0 and pythonfmu3 0.3.4 (PySlaveInstance.cpp) turn an exception into a fatal status in
    ``handle_py_exception``, which calls ``cleanPyObject``: that releases the wrapper's references to the
    slave (``pInstance_``), its class (``pClass_``, ``type(slave)``) and its log queue (``pMessages_``) but
    keeps the pointers, and freeing the instance (the destructor) releases them a second time. Each failed
    instance that is then freed takes one reference too many from the slave and from the class, and the
    process crashes once the garbage collector frees them while they are in use (libcosim, which terminates
    and frees every instance, died with SIGSEGV after a few failed runs). One extra reference to each, taken
    here before the exception leaves the slave, balances the release: the slave stays usable until it is
    freed and is freed exactly then. An importer that never frees an instance after a fatal status
    (stickslip's FMPy hosts) leaves that slave allocated until the process ends.
    """

    @functools.wraps(method)
    def entry_point(self, *args, **kwargs):
        try:
            return method(self, *args, **kwargs)
        except BaseException:
            for reference in (self, type(self), self.log_queue):
                ctypes.pythonapi.Py_IncRef(ctypes.py_object(reference))
            raise

    return entry_point


def hold_loader_namespace(namespace):
    """Take one reference to ``namespace``, the globals of the module PythonFMU loads the slave from.

    PythonFMU 0.7.0 (``findClass`` in its fmi2Instantiate) runs that module's source again in its globals,
    which it gets from ``PyModule_GetDict`` (a borrowed reference) and then releases, once per instance.
    A module whose source creates nothing that keeps its globals (a one-line import, see
    stickslip.fmu.staging) loses its namespace after a few instances unless each run takes that reference.
    """
    ctypes.pythonapi.Py_IncRef(ctypes.py_object(namespace))


# ---- serialized FMU states -----------------------------------------------------------------------------------

#: How a refused state (``_fmu_state_from_bytes``) serializes: this prefix, then the reason as UTF-8. The FMUs' loader
#: (``fmi2DeSerializeFMUstate``/``fmi3DeserializeFMUState`` in ``src/stickslip/fmu/loader``) looks for it.
REFUSED_STATE = b"refused FMU state: "
#: A serialized FMU state starts with this header: :data:`STATE_MAGIC`, the format version (:data:`STATE_FORMAT`) and
#: the CRC-32 of the identity of the FMU whose state it is (:func:`state_header`), little-endian
STATE_HEADER = struct.Struct("<8sHI")
STATE_MAGIC = b"SBFstate"
STATE_FORMAT = 1  # the version of the format of the FMUs' serialized states: the FMUs read this one only


def state_header(identity):
    """The header of the serialized states of the FMU whose identity is the text ``identity`` (its class, FMI version
    and the fields of its states: bytes of another FMU, or of another layout, are refused)."""
    return STATE_HEADER.pack(STATE_MAGIC, STATE_FORMAT, zlib.crc32(identity.encode("utf-8")))


def serialized_states(cls, to_bytes, from_bytes):
    """Give the slave class ``cls`` the library's (de)serializers of FMU states: ``_fmu_state_to_bytes`` (``to_bytes``)
    and ``_fmu_state_from_bytes`` (``from_bytes``, made never to raise), and the C loader's ``state_from_bytes``
    (``from_bytes``), which raises for bytes that are no state of the slave. ``to_bytes(state)``: the state's bytes,
    the header of :func:`state_header` first (for a refused state, :data:`REFUSED_STATE` and the reason);
    ``from_bytes(data)``: the state back, every value checked, raising with the reason (:func:`header_mismatch` for
    bytes without the header)."""
    cls.state_from_bytes = staticmethod(from_bytes)
    cls._fmu_state_from_bytes = staticmethod(functools.partial(_refused_instead, from_bytes))
    cls._fmu_state_to_bytes = staticmethod(to_bytes)


class StateBytes:
    """``to_bytes`` and ``from_bytes`` of :func:`serialized_states` for the states of the FMU whose identity is
    ``identity`` (:func:`state_header`): the header, then the parts ``pack(state)`` gives (a list of bytes);
    ``unpack(data, offset)`` gives the state back from the bytes after the header."""

    def __init__(self, identity, pack, unpack):
        self.header, self.pack, self.unpack = state_header(identity), pack, unpack

    def to_bytes(self, state):
        if refusal(state) is not None:
            return REFUSED_STATE + refusal(state).encode("utf-8")
        return b"".join([self.header, *self.pack(state)])

    def from_bytes(self, data):
        data = bytes(data)
        if not data.startswith(self.header):
            raise ValueError(f"the {len(data)} bytes are not a serialized FMU state of this FMU: "
                             f"{header_mismatch(data, self.header)}")
        return self.unpack(data, len(self.header))


def header_mismatch(data, header):
    """What in ``data`` is not the header ``header`` of this FMU's states."""
    if data.startswith(b"{"):
        return "they look like the JSON of the states of earlier versions, which this FMU no longer reads"
    if len(data) < STATE_HEADER.size:
        return f"a state starts with a header of {STATE_HEADER.size} bytes"
    magic, version, identity = STATE_HEADER.unpack_from(data)
    _, own_version, own_identity = STATE_HEADER.unpack(header)
    if magic != STATE_MAGIC:
        return f"they do not start with {STATE_MAGIC!r}"
    if version != own_version:
        return f"they are of format version {version}, and this FMU reads version {own_version}"
    return (f"they hold a state of another FMU (identity {identity:08x}, this FMU's is {own_identity:08x}: another "
            f"model, FMI version or layout of its states)")


def _refused_instead(strict, data):
    """``strict(data)``, or for bytes that are no state a refused state ``{"refused": why}``: never an exception.
    PythonFMU and pythonfmu3 call this on the slave's class, and an exception would release the calling instance's
    slave unbalanced (:func:`balance_release`), which crashed the host at its next call; the loader refuses the bytes
    instead, with the reason, and the slave's restore refuses the state in hosts without the loader
    (:func:`refusal`)."""
    try:
        return strict(data)
    except Exception as error:  # noqa: BLE001 - any failure is a refusal, see the docstring
        return {"refused": str(error)}


def refusal(state):
    """The reason why ``state`` (from ``_fmu_state_from_bytes``) is refused, or None for a state to restore."""
    return state.get("refused") if isinstance(state, dict) else None
