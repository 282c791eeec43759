"""The benchmark's FMUs: ours and the trivial floor FMU it builds, each an
:class:`~stickslip.hosts.fmpy_host.ExtractedFMU` of the FMPy host.

An FMU is extracted once (outside the timing); each timed call is one
``ExtractedFMU.simulate``, one ``fmpy.simulate_fmu`` on the extracted folder:
instantiate, initialize, every communication step, record, free.
"""

import os
import sys
from pathlib import Path

from ..fmu import loader
from ..fmu.build import CHECKOUT, announce_build, in_checkout
from ..fmu.compile_runtime import USER_CACHE
from ..fmu.python_path import preserved_sys_path
from ..hosts.fmpy_host import ExtractedFMU

FLOOR_SOURCE = Path(__file__).resolve().parent / "floor_fmu" / "TrivialFloorSlave_sbfbench.py"
#: where the benchmark builds its FMUs and C hosts: a checkout's ``build/bench/``, else the user's cache
#: (``~/.cache/stickslip/bench/``, under ``$XDG_CACHE_HOME`` if set)
BUILD_DIR = (CHECKOUT / "build" if in_checkout() else USER_CACHE) / "bench"

__all__ = ["BUILD_DIR", "ExtractedFMU", "FLOOR_SOURCE", "ensure_floor_fmu"]


def ensure_floor_fmu(build_dir=None):
    """Build ``TrivialFloor.fmu`` from :data:`FLOOR_SOURCE` into ``build_dir`` (default :data:`BUILD_DIR`),
    with the same linux64 loader as our FMU, unless it is newer than its sources; return its path."""
    from pythonfmu import FmuBuilder

    dest = Path(build_dir or BUILD_DIR) / "TrivialFloor.fmu"
    newest_source = max(path.stat().st_mtime for path in (FLOOR_SOURCE, *loader.SOURCES))
    if dest.is_file() and dest.stat().st_mtime >= newest_source:
        return dest
    announce_build(dest)
    dest.parent.mkdir(parents=True, exist_ok=True)
    partial = dest.with_name(f".{dest.name}.{os.getpid()}.part.fmu")
    try:
        with preserved_sys_path():  # PythonFMU leaves the source folder on sys.path
            FmuBuilder.build_FMU(FLOOR_SOURCE, dest=partial)
    finally:  # ... and the module imported
        sys.modules.pop(FLOOR_SOURCE.stem, None)
    loader.install(partial, "TrivialFloor")
    os.replace(partial, dest)
    return dest
