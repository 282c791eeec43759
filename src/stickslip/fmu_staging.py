"""Lay out the FMU's Python code for :func:`stickslip.fmu_build.build`: what PythonFMU loads, and how fast.

In the FMU's ``resources/``:

- ``sbf_runtime_<tag>/``: the runtime ``stickslip/core`` and the slave (``fmu_slave.py``, from
  ``fmu_src/SpringBlockFriction.py`` with its runtime import renamed), with byte-compiled files
  for the building Python in ``__pycache__`` (unchecked-hash ``.pyc``: valid whatever times the
  extraction gives the files, so a host with that Python never compiles them);
- ``springblockfriction_<tag>.py``: the module PythonFMU loads, two lines. PythonFMU 0.7.0
  compiles and runs that module's source at every ``fmi2Instantiate`` (to find the slave class
  by its MRO; with the 300-line slave there, that was 2 ms of each instantiation and a leaked
  copy of the class), so the slave's own source, imported once per process, stays out of it.
"""

import compileall
import py_compile
import re
import shutil
from dataclasses import dataclass, field
from pathlib import Path


class StagingError(RuntimeError):
    """The FMU's Python code cannot be laid out from the current sources."""


@dataclass
class StagedRuntime:
    """The staged code in a build folder: ``script`` and ``package_dir`` go to PythonFMU's builder;
    ``extra_files`` (archive name -> path) are the files its builder leaves out of the FMU."""

    script: Path
    package_dir: Path
    module: str
    extra_files: dict = field(default_factory=dict)

    def add_to(self, fmu_zip):
        """Write :attr:`extra_files` into the open FMU archive ``fmu_zip``."""
        for arcname, path in sorted(self.extra_files.items()):
            fmu_zip.write(path, arcname)


def stage_runtime(folder, tag, runtime, slave, model_name):
    """Stage the runtime folder ``runtime`` and the slave source ``slave`` (class ``model_name``) in ``folder``."""
    package, module = f"sbf_runtime_{tag}", f"springblockfriction_{tag}"
    slave_code, count = re.subn(r"\bstickslip\.core\b", package, Path(slave).read_text())
    if count != 1:
        raise StagingError(f"{slave} must import the runtime once as 'from stickslip.core import ...'")
    package_dir = Path(folder) / package
    shutil.copytree(runtime, package_dir, ignore=shutil.ignore_patterns("__pycache__", "*.pyc", "*.so"))
    (package_dir / "fmu_slave.py").write_text(slave_code)
    script = Path(folder) / f"{module}.py"
    script.write_text(f"from {package}.fmu_slave import {model_name}, hold_loader_namespace  # noqa: F401\n"
                      "hold_loader_namespace(globals())  # PythonFMU releases this module's globals once per instance\n")
    staged = StagedRuntime(script, package_dir, module)
    staged.extra_files.update(_byte_compile(package_dir))
    return staged


def _byte_compile(package_dir):
    """Unchecked-hash ``.pyc`` of every module in ``package_dir``: ``{archive name: path}``."""
    if not compileall.compile_dir(package_dir, quiet=1, invalidation_mode=py_compile.PycInvalidationMode.UNCHECKED_HASH):
        raise StagingError(f"byte-compiling {package_dir} failed")
    return {f"resources/{path.relative_to(package_dir.parent).as_posix()}": path
            for path in package_dir.glob("__pycache__/*.pyc")}
