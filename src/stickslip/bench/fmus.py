"""FMUs under ``fmpy.simulate_fmu``: ours and the trivial floor FMU the benchmark builds.

An FMU is extracted once (outside the timing); each timed call is one
``fmpy.simulate_fmu`` on the extracted folder: instantiate, initialize, every
communication step, record, free.
"""

import os
import shutil
import sys
from pathlib import Path

import fmpy

from ..fmu import loader
from ..fmu.python_path import preserved_sys_path

FLOOR_SOURCE = Path(__file__).resolve().parent / "floor_fmu" / "TrivialFloorSlave_sbfbench.py"
#: where the benchmark builds its FMUs and C hosts (relative to the current folder)
BUILD_DIR = Path("build") / "bench"


class ExtractedFMU:
    """An FMU extracted to a temporary folder; use as a context manager."""

    def __init__(self, fmu_path):
        self.model_description = fmpy.read_model_description(str(fmu_path))
        self.folder = fmpy.extract(str(fmu_path))

    def simulate(self, start_values, stop_time, output_interval, outputs, **options):
        """FMPy's result array from t = 0 to ``stop_time`` s with communication step (model exchange: output
        interval) ``output_interval`` s; ``options``: more arguments of ``fmpy.simulate_fmu``."""
        with preserved_sys_path():  # PythonFMU puts the FMU's resources on sys.path
            return fmpy.simulate_fmu(
                self.folder, model_description=self.model_description, start_time=0.0, stop_time=stop_time,
                output_interval=output_interval, start_values=start_values, output=list(outputs), **options,
            )

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        shutil.rmtree(self.folder, ignore_errors=True)


def ensure_floor_fmu(build_dir=None):
    """Build ``TrivialFloor.fmu`` from :data:`FLOOR_SOURCE` into ``build_dir`` (default :data:`BUILD_DIR`),
    with the same linux64 loader as our FMU, unless it is newer than its sources; return its path."""
    from pythonfmu import FmuBuilder

    dest = Path(build_dir or BUILD_DIR) / "TrivialFloor.fmu"
    newest_source = max(path.stat().st_mtime for path in (FLOOR_SOURCE, *loader.SOURCES))
    if dest.is_file() and dest.stat().st_mtime >= newest_source:
        return dest
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
