"""What a tool user meets in the FMUs around the model: the FMI 3 FMU's law selectors are Enumerations of the law
codes, so a tool offers the laws by name (FMI 2's stay Integers: libcosim cannot see an FMI 2 Enumeration), while
integer start values select them as before (FMPy, the C hosts); ``documentation/index.html`` lists the variable table with units and ranges, the laws and the licences
of what the FMU carries (``documentation/licenses/``); no ``sources/`` (the library's C++ sources are not those
of the FMU's binary); ``generationDateAndTime`` and the files' dates follow ``$SOURCE_DATE_EPOCH``, the same
bytes for the same sources and date; every FMU is at most 8 MB, with the CPythons it carries."""

import html
import importlib.metadata
import re
import subprocess
import sys
import textwrap
import zipfile
from pathlib import Path
from xml.etree import ElementTree as ET

import fmpy
import numpy as np
import pytest
from fmpy.validation import validate_fmu

from stickslip.core import KINETIC_LAWS, STATIC_LAWS
from stickslip.fmu import build, compile_runtime, documentation, model_description, staging, variables
from stickslip.fmu.bundle import packing
from stickslip.fmu.coupling import UNITS as COUPLING_UNITS, build_coupling
from stickslip.fmu_src.block_interface import VARIABLES
from stickslip.hosts.c_host import run_host
from stickslip.reference import parameters_from_values, simulate_reference

ROOT = Path(__file__).resolve().parents[1]

#: law selector: (its enumeration type, the laws by code)
LAWS = {"kinetic.law": ("KineticLaw", KINETIC_LAWS), "static.law": ("StaticLaw", STATIC_LAWS)}
#: a viscous kinetic law and aging static friction, chosen by their integer codes
VISCOUS_AGING = {"kinetic.law": 2, "kinetic.F0": 0.5, "kinetic.gamma": 0.4, "static.law": 2, "static.F0": 1.0,
                 "static.A": 0.2, "static.tau": 1.0, "v_drive": 0.1}
STOP, STEP = 30.0, 0.5
#: the largest an FMU may be (bytes)
MAX_FMU_SIZE = 8_000_000


def _root(path):
    with zipfile.ZipFile(path) as fmu:
        return ET.fromstring(fmu.read("modelDescription.xml"))


def test_the_fmi2_law_selectors_are_integers_of_the_codes_libcosim_sees(fmu_path):
    declared = {v.name: v for v in fmpy.read_model_description(str(fmu_path)).modelVariables}
    for name, (_, laws) in LAWS.items():
        variable = declared[name]
        assert (variable.type, variable.declaredType, variable.min, variable.max) == (
            "Integer", None, str(min(laws)), str(max(laws)))
    probe = textwrap.dedent(f"""
        from libcosimpy.CosimExecution import CosimExecution
        from libcosimpy.CosimSlave import CosimLocalSlave
        execution = CosimExecution.from_step_size(step_size=100_000_000)
        index = execution.add_local_slave(CosimLocalSlave(fmu_path={str(fmu_path)!r}, instance_name="block"))
        print(" ".join(v.name.decode() for v in execution.slave_variables(index)))
    """)
    run = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, timeout=300)
    assert run.returncode == 0, run.stderr[-3000:]
    assert set(LAWS) <= set(run.stdout.split())  # libcosim lists the variables it can set


def test_the_law_selectors_are_enumerations_of_the_unchanged_codes(fmu3_path):
    path = fmu3_path
    declared = {v.name: v for v in fmpy.read_model_description(str(path)).modelVariables}
    for name, (type_name, laws) in LAWS.items():
        variable = declared[name]
        assert (variable.type, variable.declaredType.name, int(variable.start)) == ("Enumeration", type_name, 1)
        items = [(int(i.value), i.name) for i in variable.declaredType.items]
        assert items == [(code, laws[code].NAME) for code in sorted(laws)]
    root = _root(path)
    types = {t.get("name"): t for t in root.find("TypeDefinitions").iter("EnumerationType")}
    elements = {v.get("name"): v for v in root.find("ModelVariables")}
    for name, (type_name, laws) in LAWS.items():
        assert (elements[name].tag, elements[name].get("declaredType")) == ("Enumeration", type_name)
        assert all(item.get("description").startswith(("F_K(u) = ", "F_S(t) = ")) for item in types[type_name])
    assert [n for n, e in elements.items() if e.tag == "Enumeration"] == list(LAWS)


def _reference_x():
    values = {**variables.START_VALUES, **VISCOUS_AGING}
    t = np.arange(0.0, STOP + STEP / 2, STEP)
    result = simulate_reference(parameters_from_values(values), values["x_start"], values["v_start"],
                                [(0.0, values["v_drive"], values["F_ext"])], t)
    return t, np.asarray(result.x)


@pytest.mark.parametrize("fmu, interface", [("fmu_path", "CoSimulation"), ("fmu3_path", "CoSimulation"),
                                            ("fmu3_path", "ModelExchange")])
def test_integer_start_values_select_the_laws_in_fmpy(request, fmu, interface):
    path = str(request.getfixturevalue(fmu))
    result = fmpy.simulate_fmu(path, fmi_type=interface, start_values=VISCOUS_AGING, stop_time=STOP,
                               output_interval=STEP, output=["x", "n_events"], relative_tolerance=1e-10)
    t, x = _reference_x()
    default = fmpy.simulate_fmu(path, fmi_type=interface, start_values={"v_drive": 0.1}, stop_time=STOP,
                                output_interval=STEP, output=["x"], relative_tolerance=1e-10)
    assert result["n_events"][-1] >= 2
    assert np.max(np.abs(_on_grid(result, t) - x)) < 1e-6
    assert np.max(np.abs(_on_grid(default, t) - x)) > 1e-2  # the codes changed the laws


def _on_grid(result, t):
    """``x`` at the times ``t`` (model exchange adds rows at events: the last row of each time counts)."""
    last = dict(zip(result["time"].tolist(), result["x"].tolist()))
    assert set(t.tolist()) <= set(last)
    return np.array([last[time] for time in t.tolist()])


@pytest.mark.parametrize("fmu, c_host", [("unzipped", "host"), ("unzipped3", "host3")])
def test_integer_start_values_select_the_laws_in_the_c_hosts(request, fmu, c_host):
    """FMI 2's host sets an Enumeration with fmi2SetInteger, FMI 3's with fmi3SetInt64: the same numbers as FMPy."""
    folder = request.getfixturevalue(fmu)[0]
    run = run_host(request.getfixturevalue(c_host), folder, "run", STOP, STEP, VISCOUS_AGING)
    assert run.returncode == 0, run.stderr
    x = np.array([float(line[2]) for line in run.lines if line[0] == "x"])
    t, expected = _reference_x()
    assert len(x) == len(t) and np.max(np.abs(x - expected)) < 1e-6


def test_the_fmi3_law_selectors_take_int32_calls_too(unzipped3):
    """fmi3SetInt32/fmi3GetInt32 on a selector (its type before it became an Enumeration) still work."""
    folder, description, declared = unzipped3
    fmu = fmpy.fmi3.FMU3Slave(guid=description.instantiationToken, unzipDirectory=folder, instanceName="int32",
                              modelIdentifier=description.coSimulation.modelIdentifier)
    fmu.instantiate()
    fmu.enterInitializationMode()
    law = declared["kinetic.law"].valueReference
    fmu.setInt32([law], [3])
    assert fmu.getInt32([law]) == [3] and fmu.getInt64([law]) == [3]
    fmu.setInt64([law], [2])
    assert fmu.getInt32([law]) == [2]
    fmu.exitInitializationMode()
    fmu.terminate()
    fmu.freeInstance()


def _page_rows(path):
    """The rows of the variable table of the FMU's documentation: ``{name: (causality, type, default, unit,
    allowed range, meaning)}``."""
    with zipfile.ZipFile(path) as fmu:
        page = fmu.read(documentation.INDEX).decode()
    rows = {}
    for row in re.findall(r"<tr>(.*?)</tr>", page):
        cells = [html.unescape(cell) for cell in re.findall(r"<td>(.*?)</td>", row)]
        if len(cells) == 7:
            rows[cells[0]] = tuple(cells[1:])
    return rows


def _unit(unit):
    return "1" if unit in model_description.DIMENSIONLESS else model_description.UNITS[unit][0]


@pytest.mark.parametrize("fmu", ["fmu_path", "fmu3_path"])
def test_the_documentation_lists_every_variable_with_its_unit_and_range(request, fmu):
    path = request.getfixturevalue(fmu)
    rows = _page_rows(path)
    for variable in VARIABLES:
        causality, _, default, unit, allowed, _ = rows[variable.name]
        assert (causality, unit) == (variable.causality, _unit(variable.unit)), variable.name
        if variable.enumeration is not None:
            assert allowed == ", ".join(f"{code} {name}" for code, name, _ in variable.enumeration.items)
        elif variable.allowed is not None:
            assert allowed == str(variable.allowed) and float(default) == variable.start, variable.name
        else:
            assert allowed == "any" and default == "", variable.name


def carried_pythons(names):
    """Whether the FMU whose archive names are ``names`` carries a CPython for Windows, and for Linux."""
    platforms = {packing.carried_python_platform(name) for name in names} - {None}
    return bool(platforms & {"win64", "x86_64-windows"}), bool(platforms & {"linux64", "x86_64-linux"})


@pytest.mark.parametrize("fmu, library", [("fmu_path", "pythonfmu"), ("fmu3_path", "pythonfmu3")])
def test_the_documentation_carries_the_licences_and_the_fmu_no_sources(request, fmu, library):
    path = request.getfixturevalue(fmu)
    with zipfile.ZipFile(path) as archive:
        names = archive.namelist()
        licences = {name.rsplit("/", 1)[1]: archive.read(name).decode() for name in names
                    if name.startswith(documentation.LICENSES)}
        page = archive.read(documentation.INDEX).decode()
    compiled = any(name.startswith("resources/") and name.endswith(".so") for name in names)
    python, linux_python = carried_pythons(names)  # the Windows and the Linux binaries' CPython
    expected = {"stickslip.txt", f"{library}.txt", *(("mypy.txt",) if compiled else ()),
                *(("python.txt",) if python else ())}
    carried = set(licences) - expected  # CPython's and the Debian copyright file of each library it carries
    assert expected <= set(licences) and ("cpython.txt" in carried if linux_python else not carried), carried
    assert not linux_python or "PYTHON SOFTWARE FOUNDATION LICENSE VERSION 2" in licences["cpython.txt"]
    assert all(licences[name].strip() for name in carried)
    assert not python or "PYTHON SOFTWARE FOUNDATION LICENSE VERSION 2" in licences["python.txt"]
    installed = [f for f in importlib.metadata.distribution(library).files if f.name == "LICENSE"]
    assert licences[f"{library}.txt"] == installed[0].read_text()
    assert licences["stickslip.txt"] == (ROOT / "LICENSE").read_text(encoding="utf-8")  # the one source
    assert not compiled or "PSF" in licences["mypy.txt"]
    assert all(f'href="licenses/{name}"' in page for name in licences)
    assert not [name for name in names if name.startswith("sources/")]
    root = _root(path)
    assert root.find("CoSimulation").find("SourceFiles") is None and "buildDescription" not in " ".join(names)


def test_every_fmu_is_at_most_8_mb_and_stores_only_what_is_compressed_already(fmu_path, fmu3_path, coupling_path):
    for path in (fmu_path, fmu3_path, coupling_path):
        with zipfile.ZipFile(path) as archive:
            stored = [item.filename for item in archive.infolist() if item.compress_type == zipfile.ZIP_STORED]
        assert path.stat().st_size <= MAX_FMU_SIZE, (path.name, path.stat().st_size)
        assert all(name.endswith((".zip", ".lzma")) for name in stored), (path.name, stored)


def test_without_stickslips_licence_in_its_metadata_no_fmu_is_built(tmp_path, monkeypatch):
    def no_metadata(name):
        raise importlib.metadata.PackageNotFoundError(name)

    monkeypatch.setattr(documentation.importlib.metadata, "distribution", no_metadata)
    assert "pythonfmu is licensed under MIT" in documentation.license_text("pythonfmu")
    with pytest.raises(documentation.LicenseError, match=r"stickslip's licence file \(LICENSE\) is not in"):
        build(tmp_path / "SpringBlockFriction.fmu", 2)
    assert list(tmp_path.iterdir()) == []


def test_builds_with_one_source_date_are_byte_identical_and_dated(tmp_path, monkeypatch):
    monkeypatch.setenv("SOURCE_DATE_EPOCH", "1700000000")  # 2023-11-14 22:13:20 UTC
    for version in (2, 3):
        first, second = (build(tmp_path / folder / f"{version}.fmu", version) for folder in ("a", "b"))
        assert first.read_bytes() == second.read_bytes(), f"FMI {version}"
        assert _root(first).get("generationDateAndTime") == "2023-11-14T22:13:20+00:00"
        with zipfile.ZipFile(first) as fmu:
            assert {item.date_time for item in fmu.infolist()} == {(2023, 11, 14, 22, 13, 20)}
    first, second = (build_coupling(tmp_path / folder / "ChainCoupling.fmu") for folder in ("a", "b"))
    assert first.read_bytes() == second.read_bytes()
    assert _root(first).get("generationDateAndTime") == "2023-11-14T22:13:20+00:00"


def test_the_coupling_fmu_is_documented_and_valid(tmp_path):
    path = build_coupling(tmp_path / "ChainCoupling.fmu")
    assert validate_fmu(str(path)) == []
    rows = _page_rows(path)
    assert {name: row[3] for name, row in rows.items()} == {name: _unit(u) for name, u in COUPLING_UNITS.items()}
    assert rows["kc_left"][4] == "[0.0, inf]" and rows["x"][4] == "any"
    with zipfile.ZipFile(path) as fmu:
        names = fmu.namelist()
    licences = {n.rsplit("/", 1)[1] for n in names if n.startswith("documentation/licenses/")}
    windows, linux = carried_pythons(names)
    carried = {"cpython.txt"} if linux else set()
    carried |= {"python.txt"} if windows else set()
    assert {"stickslip.txt", "pythonfmu.txt", *carried} <= licences
    assert not licences - {"stickslip.txt", "pythonfmu.txt", *carried} or "cpython.txt" in carried


def test_a_process_runs_the_fmi3_fmu_after_the_fmi2_fmu_whose_files_are_gone(fmu_path, fmu3_path, tmp_path):
    """The two FMUs share the runtime's package; the first one's extraction is removed when its run ends (FMPy),
    and the second imports what only it needs (``exchange``) from its own copy. A child process: a failure here
    crashed the host."""
    probe = textwrap.dedent(f"""
        import fmpy
        for path in ({str(fmu_path)!r}, {str(fmu3_path)!r}):
            result = fmpy.simulate_fmu(path, stop_time=2.0, output_interval=0.5, start_values={{"kinetic.law": 2}})
            print(result["x"][-1])
    """)
    run = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, cwd=tmp_path, timeout=300)
    assert run.returncode == 0, run.stderr[-3000:]
    first, second = map(float, run.stdout.split())
    assert first == second


def test_without_mypyc_the_build_says_once_that_the_runtime_stays_pure(tmp_path, monkeypatch, capsys):
    """Both FMUs built in one process where nothing compiled brought the runtime and mypyc is missing: one line says
    so and how to get it, none announces a compilation; the FMUs run."""
    monkeypatch.setattr(staging, "CACHE", tmp_path / "empty-cache")
    monkeypatch.setattr(staging, "PREBUILT", tmp_path / "none-prebuilt")
    monkeypatch.setattr(compile_runtime, "missing_tools", lambda: ["mypyc"])
    monkeypatch.setattr(staging, "_NOT_COMPILED", {})
    built = [build(tmp_path / f"{version}.fmu", version) for version in (2, 3)]
    said = capsys.readouterr().err.splitlines()
    assert not [line for line in said if "compiling" in line]
    assert [line for line in said if "pure Python" in line] == [
        next(line for line in said if "mypyc not installed" in line and "pip install 'stickslip[compile]'" in line)]
    for path in built:
        with zipfile.ZipFile(path) as fmu:
            assert not [name for name in fmu.namelist() if name.endswith(".so") and name.startswith("resources/")]
        assert fmpy.simulate_fmu(str(path), stop_time=1.0, output_interval=0.5)["x"][-1] != 0.0
