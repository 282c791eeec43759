"""A cheap start: the FMU's runtime is never compiled on the host, and instantiating leaves nothing behind."""

import gc
import io
import os
import subprocess
import sys
import textwrap
import zipfile
from pathlib import Path

from stickslip.fmu import source_tag, trim
from stickslip.fmu.sources import runtime_tag
from stickslip.fmu.compile_runtime import COMPILED_MODULES, implementation

from fmu_instances import instantiate


def test_runtime_imports_from_the_shipped_bytecode_whatever_the_file_times(unzipped, tmp_path):
    """Nothing is compiled on the host but the runtime's ``__init__.py`` (a few lines, shipped without byte code so
    that the runtime's folder holds no ``__pycache__`` folder to extract and remove)."""
    resources = Path(unzipped[0]) / "resources"
    package, runtime = resources / f"sbf_slave_{source_tag()}", resources / f"sbf_runtime_{runtime_tag()}"
    for source in [*resources.glob("*.zip"), *runtime.glob("*")]:  # an extraction gives the files any time
        os.utime(source, (2e9, 2e9))
    probe = textwrap.dedent(f"""
        import sys
        compiled = []
        sys.addaudithook(lambda event, args: event == "compile" and compiled.append(args[1]))
        sys.path.insert(0, {str(resources)!r})
        import springblockfriction_{source_tag()}
        print([str(name) for name in compiled if {str(package)!r} in str(name) or {str(runtime)!r} in str(name)])
    """)
    result = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, check=True, cwd=tmp_path)
    assert result.stdout.strip() == repr([str(runtime / "__init__.py")])


def _packed(fmu, name):
    """The zip archive ``name`` inside the open FMU archive ``fmu``."""
    return zipfile.ZipFile(io.BytesIO(fmu.read(name)))


def test_shipped_bytecode_is_unchecked_hash_based(fmu_path):
    """Every module of the runtime's package ships byte-compiled beside its source in the runtime's archive, except
    ``__init__.py`` and those that ship compiled by mypyc, and every module of the slave's package in its archive."""
    with zipfile.ZipFile(fmu_path) as fmu:
        names = fmu.namelist()
        package, slave = f"sbf_runtime_{runtime_tag()}", f"sbf_slave_{source_tag()}"
        compiled = {n.split("/")[-1].split(".")[0] for n in names if n.startswith(f"resources/{package}/")
                    and n.endswith(".so")}
        runtime = _packed(fmu, f"resources/{package}/{implementation.PACKED}")
        packed = _packed(fmu, f"resources/{slave}.zip")
        assert not [name for name in names if name.endswith(".pyc")]
        assert compiled == set(COMPILED_MODULES)
        for archive, root, ship_compiled in ((runtime, "", compiled), (packed, f"{slave}/", set())):
            modules = {n[len(root):-3] for n in archive.namelist() if n.endswith(".py")}
            pycs = [n for n in archive.namelist() if n.endswith(".pyc")]
            assert sorted(pycs) == sorted(f"{root}{m}.pyc" for m in modules - ship_compiled)
            for name in pycs:
                flags = int.from_bytes(archive.read(name)[4:8], "little")
                assert flags == 0b01  # hash-based, source not checked (PEP 552)
        assert {"_implementation", "exchange", "trajectory"} <= {n[:-3] for n in runtime.namelist()}
        assert {"fmu_slave", "block_interface"} <= {n[len(slave) + 1:-3] for n in packed.namelist()}


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


def test_the_fmus_hold_no_file_a_host_does_not_need(fmu_path, fmu3_path):
    """No module of the FMI library's builder, its package in one archive, no sources of the library's binary;
    every module of the archive byte-compiled for the building Python beside its source. The runtime's package is
    the same in both FMUs (a process that loads both shares it)."""
    runtimes = []
    for fmu, library in ((fmu_path, "pythonfmu"), (fmu3_path, "pythonfmu3")):
        with zipfile.ZipFile(fmu) as archive:
            names = archive.namelist()
            packed = zipfile.ZipFile(io.BytesIO(archive.read(f"resources/{library}.zip")))
            runtimes.append({name: archive.read(name) for name in names
                             if name.startswith(f"resources/sbf_runtime_{runtime_tag()}/")})
        assert not [name for name in names if name.startswith((f"resources/{library}/", "sources/"))]
        assert not [name for name in names if "/__pycache__/" in name]
        inside = packed.namelist()
        assert sorted(inside) == sorted([*(n for n in inside if n.endswith(".py")), *(n + "c" for n in inside
                                                                                    if n.endswith(".py"))])
        assert {f"{library}/{m}.py" for m in trim.BUILD_ONLY_MODULES} & set(inside) == set()
        assert b"builder" not in packed.read(f"{library}/__init__.py")
    assert runtimes[0] == runtimes[1] and runtimes[0]


def test_the_loader_module_imports_the_library_from_its_archive_and_not_its_builder(unzipped, tmp_path):
    """A Python without site-packages (as in a C host) gets the FMI library from the FMU's archive, and loading the
    slave imports neither the library's builder nor what only the builder needs."""
    resources = Path(unzipped[0]) / "resources"
    probe = textwrap.dedent(f"""
        import sys
        sys.path.insert(0, {str(resources)!r})
        module = __import__("springblockfriction_{source_tag()}")
        import pythonfmu
        print(pythonfmu.__file__, module.SpringBlockFriction.__name__,
              sorted({{"pythonfmu.builder", "argparse", "logging", "inspect", "xml.dom.minidom"}} & set(sys.modules)))
    """)
    result = subprocess.run([sys.executable, "-S", "-c", probe], capture_output=True, text=True, check=True,
                            cwd=tmp_path, timeout=60)
    library, slave, unwanted = result.stdout.split()
    assert library.startswith(str(resources / "pythonfmu.zip" / "pythonfmu" / "__init__.py"))  # .py or .pyc
    assert (slave, unwanted) == ("SpringBlockFriction", "[]")
