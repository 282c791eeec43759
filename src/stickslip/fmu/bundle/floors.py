"""What a host machine needs to run an FMU's ELF binaries (Linux): the oldest glibc, libstdc++ and libgcc_s each
binary accepts, read from its ELF symbol version needs (the section ``.gnu.version_r``: for each shared library,
the versions of it whose symbols the binary uses, e.g. ``GLIBC_2.34`` of ``libc.so.6``), the libraries it names
(``DT_NEEDED``), and the CPython shared library the loader starts in a process without Python. The libraries an
FMU carries beside its loader (the CPython of :mod:`stickslip.fmu.bundle.linux_python` and the libraries it needs
that are not glibc's) are measured too, and named as the FMU's own where they provide a version a binary needs.

:func:`fmu_floors` measures an FMU's entries; :func:`dependencies_text` is the FMU's
``documentation/externalDependencies.txt`` (the FMI 2.0.3 / 3.0 place for what the host must provide), which the
builder writes from them, with the Windows DLLs' needs from :mod:`stickslip.fmu.bundle.windows_needs`. Only the standard
library: no binutils needed.
"""

import re
import struct
from dataclasses import dataclass

from ..archive import SHARED_LIBRARY
from .linux_python import CARRIED_INNER
from .packing import carried_entries, carried_python_platform, packed_name
from .windows_needs import windows_needs, windows_text

#: FMI version: the oldest CPython (major, minor) the FMU's Python code runs in, which the loader checks before it
#: imports anything (FMI 2: the runtime's typing.Final; FMI 3: pythonfmu3's subscripted built-in types)
PYTHON_FLOORS = {2: (3, 8), 3: (3, 9)}

#: the file the FMI standards name for the FMU's external dependencies
DEPENDENCIES_FILE = "documentation/externalDependencies.txt"
#: version prefix: what provides it, as the host's administrator knows it
FAMILIES = {"GLIBC": "glibc (libc.so.6, libm.so.6, ld-linux)", "GLIBCXX": "libstdc++ (libstdc++.so.6)",
            "CXXABI": "libstdc++'s C++ ABI (libstdc++.so.6)", "GCC": "libgcc_s (libgcc_s.so.1)",
            "ZLIB": "zlib (libz.so.1)", "UUID": "libuuid (libuuid.so.1)", "LIBFFI": "libffi (libffi.so.8)"}
#: the symbol version prefixes of the C++ runtime
CPP_RUNTIME = ("GLIBCXX", "CXXABI", "GCC")
#: how the FMI library's own Linux binary beside the loader is named (``<model identifier>_pythonfmu.so``)
INNER_SUFFIX = "_pythonfmu.so"
#: an ELF shared library's file name: ``x.so`` or ``libx.so.1.0``
ELF_NAME = SHARED_LIBRARY
#: a numbered symbol version, e.g. GLIBC_2.34 or CXXABI_1.3.9 (GLIBC_PRIVATE and the like carry no floor)
VERSION_NAME = re.compile(r"([A-Z]+)_(\d+(?:\.\d+)*)")
#: the CPython shared library's name compiled into the loader (the one it tries after $SBF_LIBPYTHON)
LIBPYTHON_NAME = re.compile(rb"libpython3\.\d+[a-z]*\.so\.1\.0")
#: the CPython version a compiled extension module is built for, from its file name (``.cpython-311-...so``)
EXTENSION_ABI = re.compile(r"\.cpython-(\d)(\d+)")
SHT_DYNAMIC, SHT_GNU_VERNEED, DT_NEEDED = 6, 0x6FFFFFFE, 1


class NotELF(ValueError):
    """The bytes are no ELF shared object this module can read."""


@dataclass(frozen=True)
class BinaryNeeds:
    """What one ELF binary needs: ``libraries`` (its DT_NEEDED names, in order) and ``versions``
    ({library: sorted version names of it that its symbols use})."""

    libraries: tuple
    versions: dict

    def floors(self):
        """{version prefix: the newest numbered version of it this binary needs, as ``(name, number tuple)``}."""
        return newest(name for names in self.versions.values() for name in names)


def newest(version_names):
    """{prefix: ``(name, number tuple)``} of the highest-numbered name per prefix among ``version_names``."""
    out = {}
    for name in version_names:
        match = VERSION_NAME.fullmatch(name)
        if match:
            number = tuple(int(part) for part in match[2].split("."))
            if match[1] not in out or number > out[match[1]][1]:
                out[match[1]] = (name, number)
    return out


def binary_needs(data):
    """The :class:`BinaryNeeds` of the ELF shared object in ``data`` (bytes); NotELF if it is none, or is cut
    short."""
    try:
        sections, order = _sections(data)
        needs, libraries = {}, ()
        for kind, offset, size, link, info in sections:
            strings = sections[link][1] if link < len(sections) else 0
            if kind == SHT_GNU_VERNEED:
                needs = _version_needs(data, order, offset, info, strings)
            elif kind == SHT_DYNAMIC:
                libraries = _needed(data, order, offset, size, strings)
    except (struct.error, IndexError, UnicodeDecodeError) as exc:
        raise NotELF(f"a truncated or damaged ELF file ({exc})") from None
    return BinaryNeeds(libraries, needs)


def _sections(data):
    """``([(type, offset, size, link, info)] of every section header, struct byte order and ELF class)``."""
    if data[:4] != b"\x7fELF" or len(data) < 64 or data[4] not in (1, 2) or data[5] not in (1, 2):
        raise NotELF("no ELF header")
    order = ("<" if data[5] == 1 else ">") + ("Q" if data[4] == 2 else "I")
    wide = data[4] == 2
    shoff = struct.unpack_from(order[0] + order[1], data, 0x28 if wide else 0x20)[0]
    entsize, count = struct.unpack_from(order[0] + "HH", data, 0x3A if wide else 0x2E)
    if shoff == 0 or count == 0:
        raise NotELF("no section headers")
    layout = order[0] + ("IIQQQQII" if wide else "IIIIIIII")
    sections = []
    for index in range(count):
        _, kind, _, _, offset, size, link, info = struct.unpack_from(layout, data, shoff + index * entsize)
        sections.append((kind, offset, size, link, info))
    return sections, order


def _string(data, table, offset):
    """The NUL-terminated string at ``offset`` in the string table at ``table``."""
    end = data.find(b"\0", table + offset)
    if end < 0:
        raise IndexError("a string runs past the end of the file")
    return data[table + offset:end].decode()


def _version_needs(data, order, offset, count, strings):
    """{library: sorted version names} from the Verneed entries at ``offset`` (``count`` of them)."""
    needs = {}
    for _ in range(count):
        _, aux_count, file, aux, following = struct.unpack_from(order[0] + "HHIII", data, offset)
        names, at = set(), offset + aux
        for _ in range(aux_count):
            _, _, _, name, next_aux = struct.unpack_from(order[0] + "IHHII", data, at)
            names.add(_string(data, strings, name))
            at += next_aux
        needs[_string(data, strings, file)] = sorted(names)
        offset += following
    return needs


def _needed(data, order, offset, size, strings):
    """The DT_NEEDED names of the dynamic section at ``offset``."""
    entry = struct.Struct(order[0] + ("qQ" if order[1] == "Q" else "iI"))
    names = []
    for at in range(offset, offset + size, entry.size):
        tag, value = entry.unpack_from(data, at)
        if tag == 0:
            break
        if tag == DT_NEEDED:
            names.append(_string(data, strings, value))
    return tuple(names)


@dataclass(frozen=True)
class FmuFloors:
    """The measured needs of an FMU's ELF binaries: ``binaries`` ({archive name: :class:`BinaryNeeds`}),
    ``libpython`` (the CPython library name compiled into the loaders, or None) and ``compiled_for`` (the CPython
    versions, e.g. ("3.11", "3.13"), its compiled extension modules are built for, oldest first); ``windows``: the
    needs of its Windows DLLs ({archive name: :class:`~stickslip.fmu.bundle.windows_needs.WindowsNeeds`}); ``others``:
    the archive names of its binaries for other platforms (neither ELF nor DLL); ``carried``: {file name: archive
    name} of the shared libraries of the CPython the FMU carries for Linux (its libpython and the libraries beside
    it that are not glibc's), empty if it carries none; ``python_floor``: the oldest CPython its Python code runs in,
    e.g. "3.9" (:data:`PYTHON_FLOORS` of its FMI version)."""

    binaries: dict
    libpython: str | None
    compiled_for: tuple
    windows: dict
    others: tuple
    carried: dict
    python_floor: str

    def floors(self):
        """{version prefix: ``(name, numbers)``}: the newest needed version per prefix over every binary."""
        return newest(name for needs in self.binaries.values() for names in needs.versions.values()
                      for name in names)

    def provider(self, version_name):
        """The archive name of the library the FMU carries that provides ``version_name``, or None."""
        for needs in self.binaries.values():
            for library, names in needs.versions.items():
                if version_name in names and library in self.carried:
                    return self.carried[library]
        return None

    def needed_by(self, version_name):
        """The archive names of the binaries that need ``version_name``."""
        return [name for name, needs in self.binaries.items()
                if any(version_name in names for names in needs.versions.values())]


#: the suffixes of Windows binaries: DLLs and CPython's extension modules
WINDOWS_SUFFIXES = (".dll", ".pyd")


def fmu_floors(entries):
    """The :class:`FmuFloors` of an FMU's ``entries`` ({archive name: bytes}): every shared library (``.so``,
    ``.so.N``) under ``binaries/`` and ``resources/`` (NotELF if one is no ELF shared object), every ``.dll`` and
    ``.pyd`` under ``binaries/`` and every ``.pyd`` under ``resources/`` (the runtime compiled for Windows; NotPE if
    one is no PE binary); the other files of a carried CPython (its standard library, its ``._pth``) are its
    data. The CPythons packed in it (:mod:`~stickslip.fmu.bundle.packing`) are read unpacked."""
    entries = {**entries, **carried_entries(entries)}
    binaries, libpython, compiled_for = {}, None, set()
    windows = {name: windows_needs(entries[name]) for name in sorted(entries)
               if (name.startswith("binaries/") and name.endswith(WINDOWS_SUFFIXES))
               or (name.startswith("resources/") and name.endswith(".pyd"))}
    others = tuple(name for name in sorted(entries) if name.startswith("binaries/")
                   and carried_python_platform(name) is None and not ELF_NAME.fullmatch(name)
                   and not name.endswith(WINDOWS_SUFFIXES))
    carried = {name.rsplit("/", 1)[1]: name for name in sorted(entries)
               if carried_python_platform(name) is not None and ELF_NAME.fullmatch(name) and "/lib-dynload/" not in name}
    for name in sorted(entries):
        if ELF_NAME.fullmatch(name) and name.startswith(("binaries/", "resources/")):
            binaries[name] = binary_needs(entries[name])
            found = LIBPYTHON_NAME.search(entries[name]) if name.startswith("binaries/") else None
            libpython = libpython or (found[0].decode() if found else None)
            abi = EXTENSION_ABI.search(name)
            compiled_for |= {(int(abi[1]), int(abi[2]))} if abi else set()
    fmi_version = 3 if b'fmiVersion="3' in entries.get("modelDescription.xml", b"") else 2
    return FmuFloors(binaries, libpython, tuple(f"{major}.{minor}" for major, minor in sorted(compiled_for)),
                     windows, others, carried, ".".join(map(str, PYTHON_FLOORS[fmi_version])))


def dependencies_text(model_name, floors, platform="Linux x86_64"):
    """The text of the FMU's :data:`DEPENDENCIES_FILE` from its measured ``floors`` (:class:`FmuFloors`) of the
    binaries of ``platform``: what the host machine must provide, then what each binary needs."""
    lines = [f"What the host machine needs to run {model_name} on {platform}, measured from the symbol version",
             "needs of the FMU's binaries when it was built (the oldest versions that have every symbol they use):",
             ""]
    measured = floors.floors()
    inner = floors.carried.get(CARRIED_INNER)
    for prefix in sorted(measured, key=lambda p: (list(FAMILIES) + [p]).index(p)):
        name = measured[prefix][0]
        carrier = floors.provider(name)
        lines.append(f"- {FAMILIES.get(prefix, prefix)}: {name} or newer (for {', '.join(floors.needed_by(name))})"
                     + (f"; the FMU carries it ({carrier}): the loader uses that where the system lacks it (the C++ "
                        f"runtime also where the system's is older), unless the host process has loaded its own"
                        if carrier else ""))
        if inner and prefix in CPP_RUNTIME:
            lines[-1] += (f"; where the system lacks it or has an older one, the loader loads the FMU's build of that "
                          f"binary with it linked in ({inner}) instead")
    lines.append(f"- a CPython 3 shared library with its standard library: {_python_need(floors)}")
    if inner and not any(name.endswith(INNER_SUFFIX) for name in floors.binaries):
        lines.append(f"- the FMI library's binary: the FMU's build of it ({inner}), which the loader loads on every "
                     f"host: it unpacks {packed_name(inner.split('/')[1])} for it also where the host process runs a "
                     f"CPython of its own")
    lines += ["", "Each binary: the libraries it names, then the newest version it needs of each.", ""]
    for name, needs in floors.binaries.items():
        newest_names = ", ".join(found for found, _ in sorted(needs.floors().values())) or "no versioned symbols"
        lines.append(f"{name}: {', '.join(needs.libraries) or 'no libraries'}; {newest_names}")
    lines += [f"{name}: neither a Linux nor a Windows binary; not covered by this file" for name in floors.others]
    return "\n".join(lines) + "\n" + ("\n" + windows_text(model_name, floors.windows) if floors.windows else "")


def _python_need(floors):
    """The sentence on the CPython the FMU needs."""
    carried = next((name for file, name in floors.carried.items() if file.startswith("libpython3")), None)
    text = (f"the host process's own CPython ({floors.python_floor} or newer) if it runs one, else the one named by "
            f"the environment variable SBF_LIBPYTHON if set, else the one the FMU carries ({carried}, with the part of its standard "
            f"library the FMU imports; nothing else needed; packed in {packed_name(carried.split('/')[1])}, unpacked into "
            "the user's cache where it is started, or into $SBF_PYTHON_CACHE)" if carried else
            f"the host process's own CPython ({floors.python_floor} or newer) if it runs one, else "
            + (f"{floors.libpython} (the build's; the environment variable SBF_LIBPYTHON names another)"
               if floors.libpython else "one named by the environment variable SBF_LIBPYTHON"))
    if floors.compiled_for:
        text += (f". The runtime is compiled for CPython {', '.join(floors.compiled_for)}; another version runs it "
                 f"from its Python sources, with the same results")
    return text + "."
