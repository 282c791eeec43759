"""A cheap start: the FMU's runtime is never compiled on the host, and instantiating leaves nothing behind."""

import gc
import os
import subprocess
import sys
import textwrap
import zipfile
from pathlib import Path

from stickslip.fmu import source_tag

from fmu_instances import instantiate


def test_runtime_imports_from_the_shipped_bytecode_whatever_the_file_times(unzipped, tmp_path):
    resources = Path(unzipped[0]) / "resources"
    package = resources / f"sbf_runtime_{source_tag()}"
    for source in package.glob("*.py"):  # an extraction gives the files any time: later than the .pyc here
        os.utime(source, (2e9, 2e9))
    probe = textwrap.dedent(f"""
        import sys
        compiled = []
        sys.addaudithook(lambda event, args: event == "compile" and compiled.append(args[1]))
        sys.path.insert(0, {str(resources)!r})
        import {package.name}.fmu_slave
        print([name for name in compiled if {str(package)!r} in str(name)])
    """)
    result = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, check=True, cwd=tmp_path)
    assert result.stdout.strip() == "[]"


def test_shipped_bytecode_is_unchecked_hash_based(fmu_path):
    with zipfile.ZipFile(fmu_path) as fmu:
        pycs = [name for name in fmu.namelist() if name.endswith(".pyc")]
        assert len(pycs) == len([n for n in fmu.namelist() if n.startswith("resources/sbf_runtime_") and
                                 n.endswith(".py")])
        for name in pycs:
            flags = int.from_bytes(fmu.read(name)[4:8], "little")
            assert flags == 0b01  # hash-based, source not checked (PEP 552)


def test_many_instances_keep_the_loader_module_intact(unzipped):
    """PythonFMU runs the loader module's source at every instantiation and releases its globals once:
    its namespace must neither drain (the process would crash) nor collect copies of the slave."""
    variables = unzipped[2]
    loader = None
    counts = []
    for k in range(40):
        fmu = instantiate(unzipped, f"instance {k}", {"M": 1.0 + k})
        fmu.doStep(0.0, 0.5)
        assert fmu.getReal([variables["M"].valueReference]) == [1.0 + k]
        fmu.terminate()
        fmu.freeInstance()
        gc.collect()
        loader = loader or sys.modules[f"springblockfriction_{source_tag()}"]
        counts.append(sys.getrefcount(loader.__dict__))
    assert max(counts[5:]) - min(counts[5:]) <= 1
