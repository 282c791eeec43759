"""Each platform's carried CPython as one file of the FMU, which the loader unpacks only where it starts it.

The files of a platform's CPython (those :mod:`~stickslip.fmu.bundle.linux_python` and
:mod:`~stickslip.fmu.bundle.windows_python` lay out below ``python/``) go into one POSIX tar archive (ustar, sorted,
dated :data:`~stickslip.fmu.archive.ZIP_EPOCH`: the same files give the same bytes) compressed with LZMA in the
``.lzma`` format (xz-utils' ``unlzma`` reads it), at :func:`packed_name`: ``extra/stickslip/python-<platform>.tar.lzma``,
outside ``binaries/`` and ``resources/``, so that a host that extracts only those (FMPy, which has a Python of its
own) writes none of it, and a host that extracts everything writes it compressed (2.8 MB for Linux's 10.9 MB). The
loader (``loader/carried.c``) unpacks it into the user's cache, into a folder named :attr:`Packed.key` after its
content, when it must start that CPython. The compressed bytes are kept in the user's cache too
(:data:`CACHE`): compressing takes seconds, and every FMU of a build carries the same CPython.
"""

import calendar
import hashlib
import io
import lzma
import os
import tarfile
import zipfile
from dataclasses import dataclass
from pathlib import Path

from ..archive import ZIP_EPOCH
from ..compile_runtime import USER_CACHE

#: the folder (below ``binaries/<platform>/``) the build's paths of a carried CPython's files start with, and the
#: loader's paths of them (``SBF_BUNDLED_LIBPYTHON``...)
PYTHON_FOLDER = "python"
#: the FMU's folder of the packed CPythons
PACKED_FOLDER = "extra/stickslip"
#: where compressed archives are kept, named after the sha256 of the tar archive they hold
CACHE = USER_CACHE / "packed-python"
#: the LZMA preset: 9 gives the same size (within 0.1 %), a third slower
PRESET = 6


@dataclass(frozen=True)
class Packed:
    """One platform's packed CPython: ``name`` in the FMU, its ``data``, the ``key`` naming its unpacked folder,
    the size of the tar archive it holds (``tar_size``) and ``files`` ((path below ``python/``, size), ...)."""

    name: str
    data: bytes
    key: str
    tar_size: int
    files: tuple


def packed_name(platform):
    """The FMU's file of the CPython carried for ``platform`` (the folder name below ``binaries/``)."""
    return f"{PACKED_FOLDER}/python-{platform}.tar.lzma"


def pack(platform, files):
    """The :class:`Packed` CPython of ``platform`` from ``files`` ({path below ``python/``: bytes})."""
    tar = _tar(files)
    digest = hashlib.sha256(tar).hexdigest()
    return Packed(packed_name(platform), _compressed(tar, digest), f"cpython-{digest[:16]}", len(tar),
                  tuple((name, len(files[name])) for name in sorted(files)))


def pack_folder(platform, entries, folder=PYTHON_FOLDER):
    """The :class:`Packed` CPython of ``platform`` from the files of ``entries`` ({path: bytes}) below ``folder``;
    None where there are none."""
    prefix = f"{folder}/"
    files = {name.removeprefix(prefix): data for name, data in entries.items() if name.startswith(prefix)}
    return pack(platform, files) if files else None


def unpack(data):
    """{path below ``python/``: bytes} of a packed CPython's ``data``."""
    with tarfile.open(fileobj=io.BytesIO(lzma.decompress(data, format=lzma.FORMAT_ALONE))) as archive:
        return {member.name: archive.extractfile(member).read() for member in archive.getmembers() if member.isfile()}


def carried_entries(entries):
    """The files of every CPython packed in an FMU's ``entries`` ({archive name: bytes}), named as if they lay in
    ``binaries/<platform>/python/`` ({name: bytes}), for what reads the FMU's binaries (the floors)."""
    out = {}
    for name, data in entries.items():
        platform = _packed_platform(name)
        if platform is not None:
            out.update({f"binaries/{platform}/{PYTHON_FOLDER}/{path}": content for path, content in unpack(data).items()})
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
    prefix, suffix = f"{PACKED_FOLDER}/python-", ".tar.lzma"
    return name[len(prefix):-len(suffix)] if name.startswith(prefix) and name.endswith(suffix) else None


def _tar(files):
    """The bytes of a ustar archive of ``files`` (sorted, owner root, rw-r--r--, dated :data:`ZIP_EPOCH`)."""
    out = io.BytesIO()
    with tarfile.open(fileobj=out, mode="w", format=tarfile.USTAR_FORMAT) as archive:
        for name in sorted(files):
            info = tarfile.TarInfo(name)
            info.size, info.mode, info.mtime = len(files[name]), 0o644, calendar.timegm(ZIP_EPOCH)
            archive.addfile(info, io.BytesIO(files[name]))
    return out.getvalue()


def _compressed(tar, digest):
    """``tar`` compressed (``.lzma``), from :data:`CACHE` if it holds it (written there atomically)."""
    cached = CACHE / f"{digest}.lzma"
    if cached.is_file():
        return cached.read_bytes()
    data = lzma.compress(tar, format=lzma.FORMAT_ALONE, preset=PRESET)
    try:
        CACHE.mkdir(parents=True, exist_ok=True)
        partial = cached.with_name(f".{cached.name}.{os.getpid()}.part")
        partial.write_bytes(data)
        os.replace(partial, cached)
    except OSError:
        pass  # no cache: the next build compresses again
    return data
