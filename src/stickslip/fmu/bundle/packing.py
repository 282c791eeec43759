"""Each platform's carried CPython as a file of the FMU, which the loader unpacks only where it starts it.

The files of a platform's CPython (those :mod:`~stickslip.fmu.bundle.linux_python` and
:mod:`~stickslip.fmu.bundle.windows_python` lay out below ``python/``) go into one POSIX tar archive (ustar, sorted,
dated :data:`~stickslip.fmu.archive.ZIP_EPOCH`: the same files give the same bytes), run through the branch filter of
the platform's machine code (:data:`FILTERS`: xz's x86 or ARM64 BCJ filter, which makes the relative addresses of
calls and jumps absolute; 3-4 % smaller) and compressed with LZMA in the ``.lzma`` format, at :func:`packed_name`:
``extra/stickslip/python-<platform>.tar.<filter>.lzma``, outside ``binaries/`` and ``resources/``, so that a host that
extracts only those (FMPy, which has a Python of its own) writes none of it, and a host that extracts everything
writes it compressed (2.67 MB for x86_64 Linux's 10.9 MB). xz reads it without its 13-byte header: ``tail -c +14
FILE | xz -dc --format=raw --x86 --lzma1=lc=3,lp=0,pb=2,dict=8MiB`` (ARM64: ``--arm64 --lzma1=lc=1,lp=2,...``).
The Linux platforms' standard-library zips (:data:`SHARED_FILE`) go instead into one archive the platforms share,
:data:`SHARED_PACK` (LZMA, no filter), each below its platform's folder: byte code of the same modules, the x86_64
and aarch64 ones compress to 0.53 MB together, 1.00 MB apart. The loader (``loader/carried.c``) decodes its
platform's archives and undoes the filter into the user's cache, into a folder named :attr:`Packed.key` after their
content, when it must start that CPython. The compressed bytes are kept in the user's cache too (:data:`CACHE`):
compressing takes seconds, and the FMUs of a build carry the same CPythons (the FMI 3 FMU's for x86_64 Linux
differs from the FMI 2 FMUs' in one library).
"""

import calendar
import hashlib
import io
import lzma
import os
import re
import struct
import tarfile
import zipfile
from dataclasses import dataclass
from pathlib import Path

from ..archive import ZIP_EPOCH
from ..compile_runtime import USER_CACHE
from .branch_filters import arm64_branches

#: the folder (below ``binaries/<platform>/``) the build's paths of a carried CPython's files start with, and the
#: loader's paths of them (``SBF_BUNDLED_LIBPYTHON``...)
PYTHON_FOLDER = "python"
#: the FMU's folder of the packed CPythons
PACKED_FOLDER = "extra/stickslip"
#: the FMU's file of what the Linux platforms' CPythons share (:func:`shared_pack`), which each Linux loader unpacks
#: its part of with its own archive
SHARED_PACK = f"{PACKED_FOLDER}/stdlib.tar.lzma"
#: the files of a CPython that go to :data:`SHARED_PACK`: its standard-library zip
SHARED_FILE = re.compile(r"python3\d+\.zip")
#: where compressed archives are kept, named after the sha256 of the tar archive they hold
CACHE = USER_CACHE / "packed-python"
#: the size of the ``.lzma`` header: LZMA's properties (1 byte), dictionary size (4), uncompressed size (8)
HEADER_SIZE = 13
#: the LZMA preset: 9 gives the same size (within 0.1 %), a third slower
PRESET = 6
#: the dictionary size of :data:`PRESET` (8 MiB), written in the ``.lzma`` header
DICTIONARY = 8 << 20
#: the branch filter of each platform folder's machine code (none for others)
FILTERS = {"linux64": "x86", "x86_64-linux": "x86", "win64": "x86", "x86_64-windows": "x86", "aarch64-linux": "arm64"}
#: the loader's number of each filter (``SBF_CARRIED_FILTER`` in ``carried.c``)
FILTER_NUMBERS = {"": 0, "x86": 1, "arm64": 2}
#: LZMA's literal context, literal position and position bits: lc=1, lp=2 for ARM64's 4-byte instructions (0.6 %
#: smaller), LZMA's defaults otherwise (lc=3, lp=0: best for x86 code and the zipped byte code)
LITERAL_BITS = {"arm64": (1, 2, 2)}


@dataclass(frozen=True)
class Packed:
    """One platform's packed CPython: ``name`` in the FMU, its ``data``, the ``key`` naming its unpacked folder,
    the size of the tar archive it holds (``tar_size``), ``files`` ((path below ``python/``, size), ...) and the
    ``branch_filter`` run over that archive (:data:`FILTERS`, "" for none)."""

    name: str
    data: bytes
    key: str
    tar_size: int
    files: tuple
    branch_filter: str
    shared: dict


def shared_prefix(platform):
    """The folder in :data:`SHARED_PACK` of ``platform``'s files (``<platform>/``)."""
    return f"{platform}/"


def packed_name(platform):
    """The FMU's file of the CPython carried for ``platform`` (the folder name below ``binaries/``)."""
    branch_filter = FILTERS.get(platform)
    return f"{PACKED_FOLDER}/python-{platform}.tar{f'.{branch_filter}' if branch_filter else ''}.lzma"


def pack(platform, files, share=False):
    """The :class:`Packed` CPython of ``platform`` from ``files`` ({path below ``python/``: bytes}); ``share``: its
    standard-library zip goes to :data:`SHARED_PACK` (:attr:`Packed.shared`, below :func:`shared_prefix`), not into its
    own archive. Its key names the whole of ``files`` either way."""
    shared = {f"{shared_prefix(platform)}{name}": data for name, data in files.items()
              if share and SHARED_FILE.fullmatch(name)}
    own = {name: data for name, data in files.items() if f"{shared_prefix(platform)}{name}" not in shared}
    tar, branch_filter = tar_archive(own), FILTERS.get(platform, "")
    key = hashlib.sha256(tar_archive(files) if shared else tar).hexdigest()
    return Packed(packed_name(platform), _compressed(tar, hashlib.sha256(tar).hexdigest(), branch_filter),
                  f"cpython-{key[:16]}", len(tar), tuple((name, len(files[name])) for name in sorted(files)),
                  branch_filter, shared)


def pack_folder(platform, entries, folder=PYTHON_FOLDER, share=False):
    """The :class:`Packed` CPython of ``platform`` from the files of ``entries`` ({path: bytes}) below ``folder``
    (``share`` as :func:`pack`); None where there are none."""
    prefix = f"{folder}/"
    files = {name.removeprefix(prefix): data for name, data in entries.items() if name.startswith(prefix)}
    return pack(platform, files, share) if files else None


def shared_pack(packs):
    """The bytes of :data:`SHARED_PACK` holding what the :class:`Packed` ``packs`` share (None if nothing), as one
    tar archive compressed with LZMA: their standard-library zips, byte code of the same modules, compress to little
    more than one of them."""
    files = {name: data for packed in packs if packed for name, data in packed.shared.items()}
    if not files:
        return None
    tar = tar_archive(files)
    return _compressed(tar, hashlib.sha256(tar).hexdigest(), "")


def unpack_shared(data, platform):
    """{path below ``python/``: bytes} of ``platform``'s files in the :data:`SHARED_PACK` ``data``."""
    prefix = shared_prefix(platform)
    return {name.removeprefix(prefix): content for name, content in _untarred(lzma.decompress(
        data, format=lzma.FORMAT_ALONE)).items() if name.startswith(prefix)}


def unpack(data, platform):
    """{path below ``python/``: bytes} of the CPython of ``platform`` packed as ``data``."""
    branch_filter = FILTERS.get(platform, "")
    if branch_filter == "x86":  # liblzma undoes it
        tar = lzma.decompress(data[HEADER_SIZE:], format=lzma.FORMAT_RAW, filters=_filters(branch_filter))
    else:
        tar = lzma.decompress(data, format=lzma.FORMAT_ALONE)
        tar = arm64_branches(tar, encode=False) if branch_filter == "arm64" else tar
    return _untarred(tar)


def _untarred(tar):
    """{name: bytes} of the files of the tar archive ``tar``."""
    with tarfile.open(fileobj=io.BytesIO(tar)) as archive:
        return {member.name: archive.extractfile(member).read() for member in archive.getmembers() if member.isfile()}


def carried_entries(entries):
    """The files of every CPython packed in an FMU's ``entries`` ({archive name: bytes}), named as if they lay in
    ``binaries/<platform>/python/`` ({name: bytes}), for what reads the FMU's binaries (the floors)."""
    out = {}
    for name, data in entries.items():
        platform = _packed_platform(name)
        if platform is not None:
            out.update({f"binaries/{platform}/{PYTHON_FOLDER}/{path}": content
                        for path, content in unpack(data, platform).items()})
    return out


def extract(fmu_path, folder):
    """Extract the FMU at ``fmu_path`` into ``folder`` with the files of its carried CPythons beside, as
    :func:`carried_entries` names them (to read every binary of the FMU with binutils)."""
    with zipfile.ZipFile(fmu_path) as archive:
        archive.extractall(folder)
        packed = {name: archive.read(name) for name in archive.namelist() if _packed_platform(name)}
    for name, data in carried_entries(packed).items():
        (Path(folder) / name).parent.mkdir(parents=True, exist_ok=True)
        (Path(folder) / name).write_bytes(data)


def carried_python_platform(name):
    """The platform folder (``linux64``, ``win64``, ...) of the carried CPython that the name ``name`` belongs to: a
    packed CPython (:func:`packed_name`) or a file of one (``binaries/<platform>/python/...``, as
    :func:`carried_entries` names them); None for any other name."""
    parts = name.split("/")
    if len(parts) > 3 and parts[0] == "binaries" and parts[2] == PYTHON_FOLDER:
        return parts[1]
    return _packed_platform(name)


def _packed_platform(name):
    prefix = f"{PACKED_FOLDER}/python-"
    platform = name[len(prefix):].split(".tar.", 1)[0] if name.startswith(prefix) else None
    return platform if platform and name == packed_name(platform) else None


def tar_archive(files):
    """The bytes of a ustar archive of ``files`` (sorted, owner root, rw-r--r--, dated :data:`ZIP_EPOCH`)."""
    out = io.BytesIO()
    with tarfile.open(fileobj=out, mode="w", format=tarfile.USTAR_FORMAT) as archive:
        for name in sorted(files):
            info = tarfile.TarInfo(name)
            info.size, info.mode, info.mtime = len(files[name]), 0o644, calendar.timegm(ZIP_EPOCH)
            archive.addfile(info, io.BytesIO(files[name]))
    return out.getvalue()


def _filters(branch_filter):
    """liblzma's filter chain of the packs of ``branch_filter``: x86's BCJ (liblzma's), then LZMA."""
    lc, lp, pb = LITERAL_BITS.get(branch_filter, (3, 0, 2))
    return [*([{"id": lzma.FILTER_X86}] if branch_filter == "x86" else []),
            {"id": lzma.FILTER_LZMA1, "preset": PRESET, "dict_size": DICTIONARY, "lc": lc, "lp": lp, "pb": pb}]


def _encoded(tar, branch_filter):
    """``tar`` run through ``branch_filter`` and compressed: the ``.lzma`` header (LZMA's properties, the
    dictionary size, the size unknown: the stream ends with LZMA's end marker), then the LZMA stream."""
    lc, lp, pb = LITERAL_BITS.get(branch_filter, (3, 0, 2))
    header = bytes([(pb * 5 + lp) * 9 + lc]) + struct.pack("<IQ", DICTIONARY, 2 ** 64 - 1)
    data = arm64_branches(tar, encode=True) if branch_filter == "arm64" else tar
    return header + lzma.compress(data, format=lzma.FORMAT_RAW, filters=_filters(branch_filter))


def _compressed(tar, digest, branch_filter):
    """``tar`` filtered and compressed (:func:`_encoded`), from :data:`CACHE` if it holds it (written there
    atomically)."""
    cached = CACHE / f"{digest}.{branch_filter or 'plain'}.lzma"
    if cached.is_file():
        return cached.read_bytes()
    data = _encoded(tar, branch_filter)
    try:
        CACHE.mkdir(parents=True, exist_ok=True)
        partial = cached.with_name(f".{cached.name}.{os.getpid()}.part")
        partial.write_bytes(data)
        os.replace(partial, cached)
    except OSError:
        pass  # no cache: the next build compresses again
    return data
