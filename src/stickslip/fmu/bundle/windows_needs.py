"""What a host machine needs to run an FMU's PE binaries (Windows DLLs): the DLLs each one imports (its import
table, with the functions it takes from each), the Windows version its header asks for (the subsystem version,
which Windows checks when it loads the DLL; the operating system version beside it), and the Windows version the
newest Windows API function it imports needs (from :data:`API_SINCE`, Microsoft's "minimum supported client").

:func:`windows_needs` reads one DLL; :func:`windows_text` is the Windows part of the FMU's
``documentation/externalDependencies.txt`` (:mod:`stickslip.fmu.bundle.floors` writes the rest). Only the standard
library: no binutils needed.
"""

import struct
from dataclasses import dataclass

#: Windows version number (major, minor): its name
RELEASES = {(5, 1): "Windows XP", (5, 2): "Windows XP x64", (6, 0): "Windows Vista", (6, 1): "Windows 7",
            (6, 2): "Windows 8", (6, 3): "Windows 8.1", (10, 0): "Windows 10"}
#: the Windows API functions newer than Windows XP that the loader or a runtime's start-up code may import: the
#: first Windows version whose system DLLs export them (Microsoft's "minimum supported client")
API_SINCE = {**dict.fromkeys(("FlsAlloc", "FlsFree", "FlsGetValue", "FlsSetValue", "InitOnceExecuteOnce",
                              "InitOnceBeginInitialize", "InitOnceComplete", "AcquireSRWLockExclusive",
                              "ReleaseSRWLockExclusive", "AcquireSRWLockShared", "ReleaseSRWLockShared",
                              "InitializeSRWLock", "InitializeConditionVariable", "SleepConditionVariableSRW",
                              "SleepConditionVariableCS", "WakeConditionVariable", "WakeAllConditionVariable",
                              "InitializeCriticalSectionEx", "GetFinalPathNameByHandleW", "GetTickCount64",
                              "CreateSymbolicLinkW", "GetLocaleInfoEx", "LCMapStringEx", "CompareStringEx",
                              "GetUserDefaultLocaleName", "CreateEventExW", "CreateSemaphoreExW",
                              "GetFileInformationByHandleEx", "SetFileInformationByHandle"), (6, 0)),
             **dict.fromkeys(("K32EnumProcessModules", "K32GetModuleBaseNameW", "K32GetModuleFileNameExW",
                              "K32GetModuleInformation", "TryAcquireSRWLockExclusive"), (6, 1)),
             **dict.fromkeys(("GetSystemTimePreciseAsFileTime", "SetDefaultDllDirectories", "AddDllDirectory",
                              "RemoveDllDirectory", "GetCurrentPackageId", "CreateFile2"), (6, 2))}
#: what provides the Visual C++ runtime's DLLs
VISUAL_CPP = ("the Microsoft Visual C++ 2015-2022 Redistributable (x64; CPython for Windows brings VCRUNTIME140.dll "
              "and VCRUNTIME140_1.dll, not MSVCP140.dll)")
#: what provides an imported DLL, by the start of its lower-case name (the first match counts)
PROVIDERS = (("api-ms-win-crt-", "the Universal C Runtime (part of Windows 10 and newer; on Windows 7 SP1 and 8.1 "
                                 "Windows Update KB2999226 or the Visual C++ 2015-2022 Redistributable installs it)"),
             ("msvcp140", VISUAL_CPP), ("vcruntime140", VISUAL_CPP),
             ("python3", "CPython for Windows (python3.dll, the stable ABI's forwarder, beside the python3XY.dll "
                         "the loader starts)"),
             ("", "Windows itself"))
#: what provides an imported DLL that the FMU carries itself (the CPython of its Windows binaries, whose folder the
#: loader loads them from)
CARRIED = ("the FMU itself, in python/ beside its Windows binaries (the CPython they start where the host process has "
           "none; in a Python host the host's CPython brings them)")
#: the index of the import table among the optional header's data directories
IMPORT_DIRECTORY = 1


class NotPE(ValueError):
    """The bytes are no PE (Windows) binary this module can read."""


@dataclass(frozen=True)
class WindowsNeeds:
    """What one PE binary needs: ``imports`` ({DLL name: the names of the functions it imports from it, in the
    table's order; ordinal imports as ``#N``}), ``subsystem`` and ``system`` (the header's subsystem and operating
    system versions, ``(major, minor)``)."""

    imports: dict
    subsystem: tuple
    system: tuple

    def newest_api(self):
        """``(Windows version, function name)`` of the imported function in :data:`API_SINCE` that needs the
        newest Windows, or None if it imports none of them."""
        known = [(API_SINCE[name], name) for names in self.imports.values() for name in names if name in API_SINCE]
        return max(known) if known else None

    def floor(self):
        """The oldest Windows version, ``(major, minor)``, that loads this binary and has every function it
        imports (of those :data:`API_SINCE` knows)."""
        newest = self.newest_api()
        return max(self.subsystem, newest[0]) if newest else self.subsystem


def windows_needs(data):
    """The :class:`WindowsNeeds` of the PE binary in ``data`` (bytes); NotPE if it is none, or is cut short."""
    try:
        header = _pe_header(data)
        optional = header + 24
        magic = struct.unpack_from("<H", data, optional)[0]
        if magic not in (0x10B, 0x20B):
            raise NotPE(f"an unknown optional header (magic {magic:#x})")
        system = struct.unpack_from("<HH", data, optional + 40)
        subsystem = struct.unpack_from("<HH", data, optional + 48)
        directories = optional + (112 if magic == 0x20B else 96)
        count = struct.unpack_from("<I", data, directories - 4)[0]
        table = struct.unpack_from("<I", data, directories + 8 * IMPORT_DIRECTORY)[0] if count > 1 else 0
        sections = _sections(data, header)
        imports = _imports(data, sections, table, magic == 0x20B) if table else {}
    except (struct.error, IndexError, UnicodeDecodeError) as exc:
        raise NotPE(f"a truncated or damaged PE file ({exc})") from None
    return WindowsNeeds(imports, tuple(subsystem), tuple(system))


def _pe_header(data):
    """The offset of the ``PE\\0\\0`` signature (the COFF header follows it)."""
    if data[:2] != b"MZ" or len(data) < 64:
        raise NotPE("no MZ header")
    header = struct.unpack_from("<I", data, 0x3C)[0]
    if data[header:header + 4] != b"PE\0\0":
        raise NotPE("no PE signature")
    return header


def _sections(data, header):
    """``[(virtual address, virtual size, file offset)]`` of every section."""
    count = struct.unpack_from("<H", data, header + 6)[0]
    start = header + 24 + struct.unpack_from("<H", data, header + 20)[0]
    sections = []
    for index in range(count):
        size, address, _, raw = struct.unpack_from("<8xIIII", data, start + 40 * index)
        sections.append((address, size, raw))
    return sections


def _offset(sections, rva):
    """The file offset of the relative virtual address ``rva``."""
    for address, size, raw in sections:
        if address <= rva < address + size:
            return raw + rva - address
    raise IndexError(f"address {rva:#x} is in no section")


def _string(data, offset):
    """The NUL-terminated ASCII string at file ``offset``."""
    end = data.find(b"\0", offset)
    if end < 0:
        raise IndexError("a name runs past the end of the file")
    return data[offset:end].decode("ascii")


def _imports(data, sections, table, wide):
    """{DLL name: imported function names} from the import descriptors at ``table`` (an address)."""
    imports, at = {}, _offset(sections, table)
    thunk, ordinal_bit = ("<Q", 1 << 63) if wide else ("<I", 1 << 31)
    while True:
        lookup, _, _, name, bound = struct.unpack_from("<IIIII", data, at)
        if not (lookup or name or bound):
            return imports
        names, entry = [], _offset(sections, lookup or bound)
        while (value := struct.unpack_from(thunk, data, entry)[0]) != 0:
            names.append(f"#{value & 0xFFFF}" if value & ordinal_bit else
                         _string(data, _offset(sections, value & 0x7FFFFFFF) + 2))
            entry += struct.calcsize(thunk)
        imports[_string(data, _offset(sections, name))] = names
        at += 20


def provider(dll, carried=()):
    """What provides the imported ``dll`` (a sentence from :data:`PROVIDERS`), or :data:`CARRIED` if it is among the
    archive names ``carried`` (the FMU's own binaries)."""
    if any(name.rsplit("/", 1)[-1].lower() == dll.lower() for name in carried):
        return CARRIED
    return next(text for start, text in PROVIDERS if dll.lower().startswith(start))


def release(version):
    """The name of the Windows ``version`` ``(major, minor)``, e.g. "Windows 7 (6.1)"."""
    name = RELEASES.get(tuple(version), "Windows")
    return f"{name} ({version[0]}.{version[1]})"


def windows_text(model_name, binaries):
    """The Windows part of the FMU's dependency file from ``binaries`` ({archive name: :class:`WindowsNeeds`}):
    the oldest Windows, what provides the DLLs they import, then what each binary imports."""
    floor = max(needs.floor() for needs in binaries.values())
    lines = [f"What the host machine needs to run {model_name} on Windows x86_64, measured from the import tables",
             "and headers of the FMU's Windows binaries when it was built:", "",
             f"- {release(floor)} or newer: {_floor_reasons(binaries, floor)}"]
    by_provider = {}
    for name, needs in binaries.items():
        for dll in needs.imports:
            dlls, users = by_provider.setdefault(provider(dll, binaries), ({}, {}))
            dlls[dll], users[name] = None, None
    texts = [CARRIED, *(text for _, text in PROVIDERS)]
    for text, (dlls, users) in sorted(by_provider.items(), key=lambda item: texts.index(item[0])):
        lines.append(f"- {text}: {', '.join(dlls)} (for {', '.join(users)})")
    lines += ["", "Each Windows binary: its subsystem version (its operating system version), the newest Windows API function it imports, then the "
              "DLLs it imports.", ""]
    for name, needs in binaries.items():
        newest = needs.newest_api()
        api = f"{newest[1]} needs {release(newest[0])}" if newest else "no function newer than Windows XP"
        lines.append(f"{name}: subsystem {_dotted(needs.subsystem)} (operating system {_dotted(needs.system)}); "
                     f"{api}; {', '.join(needs.imports) or 'no DLLs'}")
    return "\n".join(lines) + "\n"


def _dotted(version):
    """``(major, minor)`` as "major.minor"."""
    return f"{version[0]}.{version[1]}"


def _floor_reasons(binaries, floor):
    """Why the oldest Windows is ``floor``: the binaries whose subsystem version or newest function asks for it."""
    reasons = [f"{name} has subsystem version {_dotted(floor)}" for name, needs in binaries.items()
               if needs.subsystem == floor]
    reasons += [f"{name} imports {needs.newest_api()[1]}" for name, needs in binaries.items()
                if needs.newest_api() and needs.newest_api()[0] == floor]
    return "; ".join(reasons)
