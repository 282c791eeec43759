"""setuptools hook: compile the runtime's hot modules with mypyc (src/stickslip/fmu/compile_runtime.py), and, in a
second process at the same time, the FMUs' renamed copy of them into stickslip/fmu/prebuilt.

Optional: without mypyc or a C compiler the package installs as pure Python, and says so.
The packages are those below src/ plus three top-level folders mapped in: the slaves' sources fmu_src/ as
stickslip.fmu_src (the builders read them from there), and the scenario and system files scenarios/ and systems/ as
the data-only packages stickslip.scenario_files and stickslip.system_files (the command line finds them by name,
stickslip.cli.named_files). Everything else is in pyproject.toml.
"""

import importlib.util
import os
import subprocess
import sys
import time
from pathlib import Path

from setuptools import find_packages, setup
from setuptools.command.build_ext import build_ext

SRC = Path(__file__).resolve().parent / "src"
CORE = SRC / "stickslip" / "core"
_spec = importlib.util.spec_from_file_location("compile_runtime", SRC / "stickslip" / "fmu" / "compile_runtime.py")
compile_runtime = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(compile_runtime)


class BuildCompiledRuntime(build_ext):
    """build_ext that removes compiled files of older sources first, says how far it is, and stamps the new ones;
    it compiles the extensions in parallel, one per core (the module shims beside the large group library)."""

    def finalize_options(self):
        super().finalize_options()
        if self.parallel is None:
            self.parallel = os.cpu_count() or 1

    def run(self):
        if self.inplace:
            compile_runtime.remove_compiled(SRC, CORE)
        fmu_runtime = self._start_fmu_runtime()
        self.n_started, start = 0, time.monotonic()
        print(f"stickslip: compiling the C that mypyc made of the runtime's {len(compile_runtime.COMPILED_MODULES)} "
              f"hot modules: {len(self.extensions)} extensions, the first the largest", file=sys.stderr)
        super().run()
        target = CORE if self.inplace else Path(self.build_lib) / "stickslip" / "core"
        built = [name for name in compile_runtime.COMPILED_MODULES if list(target.glob(f"{name}.*.so"))]
        if len(built) == len(compile_runtime.COMPILED_MODULES):
            compile_runtime.write_stamp(target)
            if self.editable_mode and target != CORE:  # an editable install: setuptools copies them into CORE
                compile_runtime.write_stamp(CORE)
            print(f"stickslip: the runtime's hot modules are compiled (mypyc) in {time.monotonic() - start:.0f} s",
                  file=sys.stderr)
        else:
            print("stickslip: compiling the runtime failed (no C compiler?): it runs as pure Python", file=sys.stderr)
        if fmu_runtime.wait() != 0:
            print("stickslip: compiling the FMUs' runtime failed: the FMUs' builder compiles it", file=sys.stderr)

    def _start_fmu_runtime(self):
        """Start compiling the FMUs' copy of the runtime into the package's ``fmu/prebuilt`` (one process beside
        this build's: on two cores the two compilations take the time of one), so that FMUs built where this
        package is installed carry compiled modules without mypy there."""
        lib = SRC if self.inplace else Path(self.build_lib)
        print("stickslip: compiling the FMUs' copy of the runtime (mypyc) beside it", file=sys.stderr)
        return subprocess.Popen([sys.executable, str(SRC / "stickslip" / "fmu" / "compile_runtime.py"), str(CORE),
                                 str(lib / "stickslip" / "fmu" / compile_runtime.PREBUILT.name)])

    def build_extension(self, ext):
        self.n_started += 1
        print(f"stickslip: extension {self.n_started}/{len(self.extensions)}: {ext.name}", file=sys.stderr)
        super().build_extension(ext)


def _extensions():
    try:
        return compile_runtime.extensions("src/stickslip/core")
    except ImportError as exc:  # mypyc missing: pyproject's build-system requires it, a non-isolated build may not
        print(f"stickslip: mypyc is not available ({exc}): the runtime runs as pure Python", file=sys.stderr)
        return []


#: package -> the top-level folder it is mapped from
MAPPED = {"stickslip.fmu_src": "fmu_src", "stickslip.scenario_files": "scenarios", "stickslip.system_files": "systems"}

setup(
    packages=[*find_packages("src"), *MAPPED],
    package_dir={"": "src", **MAPPED},
    ext_modules=_extensions(),
    cmdclass={"build_ext": BuildCompiledRuntime},
)
