"""The compiled floor: ``CFloor.fmu``, an FMI 2.0 co-simulation FMU in C that does nothing
(``c_floor_fmu/CFloor.c``: one output ``x``, one input ``u``, an empty ``fmi2DoStep``; FMU states that are copies of
the two variables, serialized as many bytes as a state of the block FMU).

Built with the machine's C compiler (``$CC``, default ``cc``) into the benchmark's build folder: what a
host pays per call when the FMU itself costs nothing, the physical floor of an FMI call.
"""

import os
import shutil
import subprocess
import tempfile
import zipfile
from pathlib import Path

from ..hosts.c_host import HostBuildError

SOURCE_DIR = Path(__file__).resolve().parent / "c_floor_fmu"
SOURCES = (SOURCE_DIR / "CFloor.c", SOURCE_DIR / "modelDescription.xml")


def ensure_c_floor_fmu(build_dir):
    """``build_dir/CFloor.fmu``, compiled unless it is newer than its sources; :class:`HostBuildError` if no C
    compiler works here."""
    dest = Path(build_dir) / "CFloor.fmu"
    if dest.is_file() and dest.stat().st_mtime >= max(path.stat().st_mtime for path in SOURCES):
        return dest
    compiler = os.environ.get("CC") or "cc"
    if shutil.which(compiler) is None:
        raise HostBuildError(f"no C compiler: {compiler!r} not found (set CC)")
    dest.parent.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory() as tmp:
        binary = Path(tmp) / "CFloor.so"
        result = subprocess.run([compiler, "-O2", "-shared", "-fPIC", "-fvisibility=hidden", "-o", str(binary),
                                 str(SOURCES[0])], capture_output=True, text=True)
        if result.returncode != 0:
            raise HostBuildError(f"{compiler} failed to compile {SOURCES[0].name}:\n{result.stderr}")
        partial = dest.with_name(f".{dest.name}.{os.getpid()}.part")
        with zipfile.ZipFile(partial, "w", zipfile.ZIP_DEFLATED) as archive:
            archive.write(SOURCES[1], "modelDescription.xml")
            archive.write(binary, "binaries/linux64/CFloor.so")
    os.replace(partial, dest)
    return dest
