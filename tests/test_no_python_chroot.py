"""The FMUs on a Linux machine with nothing but glibc: the project's C hosts in a chroot that holds only the files
``ldd`` lists for them and the extracted FMUs, so that the only CPython, standard library and C++ runtime there are
the ones the FMUs carry (``stickslip.fmu.bundle.linux_python``). Their results equal FMPy's on the full machine, bit
for bit (the same CPython and runtime). Outside the chroot: which libraries the processes load (``LD_DEBUG=files``),
so that the carried CPython is the one used where no other is, and a host's own Python, ``$SBF_LIBPYTHON`` and the
system's C++ runtime keep precedence. Skipped, saying why, where this process may not chroot (not even in a user
namespace: ``unshare -r``)."""

import re
import shutil
import subprocess
import sys
import textwrap
import zipfile
from pathlib import Path
from xml.etree import ElementTree

import pytest

from stickslip.fmu import build
from stickslip.fmu.bundle.floors import DEPENDENCIES_FILE
from stickslip.fmu.bundle import linux_python, packing
from stickslip.fmu.loader.install import LIBPYTHON_VARIABLE, build_libpython
from stickslip.hosts.c_host import host_env, run_host
from stickslip.hosts.fmpy_host import run_fmu
from stickslip.suite.scenario import load_scenario

import machine_needs

SCENE = load_scenario(Path(__file__).resolve().parents[1] / "scenarios" / "elmer-fig3-v0.1.toml")
START = SCENE.start_values()
SHORT = 20.0  # s: stop time of the runs that check behaviour rather than the whole scene
BAD_MASS = "M = -1.0 kg is out of range: allowed is a finite value in (0, inf)"
COUPLING_START = {"kc_left": 2.0, "kc_right": 3.0, "x_left": 0.3, "x": 0.05, "x_right": -0.1}  # N/m, m
#: the FMUs' folders in the chroot
FOLDERS = {"fmu2": "fmu_path", "fmu3": "fmu3_path", "coupling": "coupling_path"}
#: a library the dynamic linker loads, as LD_DEBUG=files reports it
LOADED = re.compile(r"file=(\S+) \[\d+\];\s+(?:dynamically loaded|needed)")


def _ldd_files(binary):
    """The files ``ldd`` lists for ``binary``, by their paths."""
    output = subprocess.run(["ldd", str(binary)], capture_output=True, text=True, check=True).stdout
    return sorted({match for match in re.findall(r"(/\S+) \(0x", output)})


def _chroot_wrapper(root, host):
    """The command prefix that runs a program with ``root`` as its ``/``: chroot, else chroot in a user namespace
    where this process may make one; skip if neither works."""
    reasons = []
    for wrapper in (["chroot", str(root)], ["unshare", "-r", "chroot", str(root)]):
        if shutil.which(wrapper[0]) is None:
            reasons.append(f"{wrapper[0]} is not installed")
            continue
        result = subprocess.run([*wrapper, f"/{host.name}"], capture_output=True, text=True, env=host_env())
        if not result.stderr.startswith((f"{wrapper[0]}:", "chroot:")):  # it ran: the host's usage and code
            return wrapper
        reasons.append(result.stderr.strip())
    pytest.skip(f"this process may not chroot: {'; '.join(reasons)}")


@pytest.fixture(scope="module")
def jail(request, tmp_path_factory, host, host3):
    """``(root folder, wrapper)``: a chroot with the C hosts, the glibc files they need and the three FMUs
    extracted (``/fmu2``, ``/fmu3``, ``/coupling``), and the command prefix that runs a program in it."""
    root = tmp_path_factory.mktemp("jail")
    for binary in (host, host3):
        shutil.copy2(binary, root / binary.name)
        for library in _ldd_files(binary):
            (root / library.lstrip("/")).parent.mkdir(parents=True, exist_ok=True)
            shutil.copy2(library, root / library.lstrip("/"))
    for folder, fixture in FOLDERS.items():
        with zipfile.ZipFile(request.getfixturevalue(fixture)) as fmu:
            fmu.extractall(root / folder)
    return root, _chroot_wrapper(root, host)


def run_in(jail, host, folder, mode, stop, start=START, output="x", env=None):
    """Run ``host`` (the C host outside, copied into the chroot) on the FMU at ``/folder`` in the chroot."""
    root, wrapper = jail
    return run_host(root / Path(host).name, root / folder, mode, stop, SCENE.output_interval, start, output=output,
                    env=env, wrapper=wrapper, root=root)


def completed(run):
    assert run.completed, f"host exit {run.returncode}: {run.lines[-3:]} {run.logs} {run.stderr[-2000:]}"
    return run


@pytest.fixture(scope="module")
def fmpy_runs(fmu_path, fmu3_path, coupling_path):
    """FMPy's (times, values) of an FMU ("fmu2", "fmu3", "coupling") up to ``stop`` s on the full machine."""
    runs = {}

    def series(folder, stop, start=START, output="x"):
        key = (folder, stop, output)
        if key not in runs:
            path = {"fmu2": fmu_path, "fmu3": fmu3_path, "coupling": coupling_path}[folder]
            result = run_fmu(path, start, stop, SCENE.output_interval, outputs=[output])
            runs[key] = (list(result["time"]), list(result[output]))
        return runs[key]

    return series


def test_the_chroot_holds_no_python_and_no_cpp_runtime_but_the_fmus(jail):
    root, _ = jail
    outside_fmus = [path for path in root.rglob("*") if path.is_file() and path.relative_to(root).parts[0]
                    not in FOLDERS]
    assert outside_fmus and not [path for path in outside_fmus if re.match(r"lib(python|stdc\+\+|gcc_s|ffi|z)\b",
                                                                           path.name)]
    assert not [path for path in outside_fmus if path.suffix == ".py" or path.name.endswith(".zip")]


@pytest.mark.parametrize("folder, binary", [("fmu2", "host"), ("fmu3", "host3")])
def test_the_scene_in_the_chroot_equals_fmpy_on_the_full_machine(jail, fmpy_runs, folder, binary, request):
    run = completed(run_in(jail, request.getfixturevalue(binary), folder, "run", SCENE.stop_time))
    assert run.series("x") == fmpy_runs(folder, SCENE.stop_time)
    assert run.logs == []


@pytest.mark.parametrize("folder, binary", [("fmu2", "host"), ("fmu3", "host3")])
def test_a_bad_parameter_in_the_chroot_is_an_error_naming_it(jail, fmpy_runs, folder, binary, request):
    run = completed(run_in(jail, request.getfixturevalue(binary), folder, "bad", SHORT, [*START.items(), ("M", -1.0)]))
    assert int(run.value("status")[1]) == 3  # fmi2Error / fmi3Error at ExitInitializationMode
    assert [(status, instance) for status, instance, _ in run.logs] == [(3, "bad")]
    assert BAD_MASS in run.logs[0][2]
    assert run.series("x") == fmpy_runs(folder, SHORT)  # the bad instance freed, a new one runs


@pytest.mark.parametrize("folder, binary", [("fmu2", "host"), ("fmu3", "host3")])
def test_fmu_states_in_the_chroot_replay_exactly(jail, fmpy_runs, folder, binary, request):
    """Got, set, serialized and deserialized, the state at SHORT/2 replays the run's second half exactly."""
    run = completed(run_in(jail, request.getfixturevalue(binary), folder, "state", SHORT))
    times, x = fmpy_runs(folder, SHORT)
    second_half = (times[len(times) // 2 + 1:], x[len(x) // 2 + 1:])
    assert run.series("x") == run.series("r") == run.series("d") == second_half


@pytest.mark.parametrize("folder, binary, mode", [("fmu2", "host", "two"), ("fmu2", "host", "threads"),
                                                  ("fmu3", "host3", "unload")])
def test_two_instances_in_the_chroot(jail, fmpy_runs, folder, binary, mode, request):
    run = completed(run_in(jail, request.getfixturevalue(binary), folder, mode, SHORT))
    tags = ("x",) if mode == "unload" else ("a", "b")
    for tag in tags:
        assert run.series(tag)[1][-1] == fmpy_runs(folder, SHORT)[1][-1]
    if mode == "unload":  # both threads' lines, interleaved
        assert sorted(run.series("x")[1]) == sorted(fmpy_runs(folder, SHORT)[1] * 2)
    else:
        assert run.series("a") == run.series("b") == fmpy_runs(folder, SHORT)


def test_the_coupling_fmu_in_the_chroot_equals_fmpy(jail, fmpy_runs, host):
    run = completed(run_in(jail, host, "coupling", "run", SHORT, COUPLING_START, output="F"))
    assert run.series("x") == fmpy_runs("coupling", SHORT, COUPLING_START, "F")
    assert run.series("x")[1][-1] == 2.0 * (0.3 - 0.05) + 3.0 * (-0.1 - 0.05)


def test_pythonhome_and_pythonpath_do_not_reach_the_carried_python(jail, fmpy_runs, host):
    """The carried CPython's path is its ._pth file's: a host's PYTHONHOME or PYTHONPATH (for another Python) does
    not break it."""
    run = completed(run_in(jail, host, "fmu2", "run", SHORT, env={"PYTHONHOME": "/nonexistent",
                                                                  "PYTHONPATH": "/nonexistent"}))
    assert run.series("x") == fmpy_runs("fmu2", SHORT)


# ---------------------------------------------------------------------------
# which Python and which C++ runtime, on the full machine and in the chroot
# ---------------------------------------------------------------------------

def loaded_libraries(stderr):
    """The files the dynamic linker loaded, from the ``LD_DEBUG=files`` lines in ``stderr``."""
    return set(LOADED.findall(stderr))


def bundled(folder, name):
    """The path of the file ``name`` in the CPython bundle of the FMU extracted to ``folder`` (FMI 2)."""
    return str(Path(folder).resolve() / "binaries" / "linux64" / "python" / name)


def test_the_carried_python_runs_a_c_host_and_the_system_keeps_its_libraries(unzipped, host):
    """Outside the chroot a C host has no Python: the FMU's own is started (before the build's), while the
    system's libstdc++ and zlib, which it has, are used rather than the FMU's copies."""
    run = completed(run_host(host, unzipped[0], "run", 1.0, SCENE.output_interval, START, env={"LD_DEBUG": "files"}))
    loaded = loaded_libraries(run.stderr)
    assert bundled(unzipped[0], f"libpython{sys.version_info[0]}.{sys.version_info[1]}.so.1.0") in loaded
    assert build_libpython()[0] not in loaded
    assert not [path for path in loaded if "/python/lib/" in path]
    assert any(Path(path).name == "libstdc++.so.6" for path in loaded)


def test_in_the_chroot_the_fmus_cpp_runtime_and_libraries_are_used(jail, fmpy_runs, host):
    run = completed(run_in(jail, host, "fmu2", "run", 1.0, env={"LD_DEBUG": "files"}))
    loaded = loaded_libraries(run.stderr)
    for name in ("libstdc++.so.6", "libgcc_s.so.1", "libffi.so.8", "libz.so.1"):
        assert f"/fmu2/binaries/linux64/python/lib/{name}" in loaded, sorted(loaded)
    assert run.series("x") == fmpy_runs("fmu2", 1.0)


def test_the_fmi3_fmus_cpython_carries_pythonfmu3s_binary_for_the_chroot_alone(jail, fmpy_runs, host3, unzipped3):
    """pythonfmu3's binary built with its C++ runtime linked in, which the FMI 3 FMU's CPython carries in place of
    libstdc++: loaded in the chroot, with no C++ runtime; on the full machine the FMU's own binary is."""
    run = completed(run_in(jail, host3, "fmu3", "run", 1.0, env={"LD_DEBUG": "files"}))
    loaded = loaded_libraries(run.stderr)
    assert f"/fmu3/binaries/x86_64-linux/python/lib/{linux_python.CARRIED_INNER}" in loaded, sorted(loaded)
    # asked for by the FMU's own binary, which then does not load, and found nowhere
    assert not [path for path in loaded if re.search(r"/lib(stdc\+\+|gcc_s)", path)], sorted(loaded)
    assert run.series("x") == fmpy_runs("fmu3", 1.0)
    outside = completed(run_host(host3, unzipped3[0], "run", 1.0, SCENE.output_interval, START,
                                 env={"LD_DEBUG": "files"}))
    loaded = loaded_libraries(outside.stderr)
    assert not [path for path in loaded if "/python/lib/" in path]
    assert str(Path(unzipped3[0]).resolve() / "binaries/x86_64-linux/SpringBlockFriction_pythonfmu.so") in loaded


def test_sbf_libpython_keeps_precedence_over_the_carried_python(unzipped, host):
    libpython = build_libpython()[0]
    if not libpython:
        pytest.skip("this Python has no shared library to name in SBF_LIBPYTHON")
    run = completed(run_host(host, unzipped[0], "run", 1.0, SCENE.output_interval, START,
                             env={"LD_DEBUG": "files", LIBPYTHON_VARIABLE: libpython}))
    loaded = loaded_libraries(run.stderr)
    assert libpython in loaded and not [path for path in loaded if "/python/libpython" in path]


def test_a_python_host_uses_its_own_python(fmu_path, tmp_path):
    """FMPy in a child of this Python: the FMU's carried CPython is never loaded."""
    script = textwrap.dedent(f"""
        import fmpy
        result = fmpy.simulate_fmu({str(fmu_path)!r}, stop_time=1.0, output_interval=0.1, output=["x"])
        print(repr(float(result["x"][-1])))
    """)
    result = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, cwd=tmp_path,
                            env={**host_env(), "LD_DEBUG": "files"}, timeout=300)
    assert result.returncode == 0, result.stderr[-3000:]
    loaded = loaded_libraries(result.stderr)
    assert any("SpringBlockFriction_pythonfmu.so" in path for path in loaded)  # the FMU did run here
    assert not [path for path in loaded if "/python/libpython" in path or "/python/lib/" in path]


def test_fmus_that_carry_a_python_for_every_platform_need_no_execution_tool(fmu_path, fmu3_path, coupling_path):
    for path in (fmu_path, fmu3_path, coupling_path):
        with zipfile.ZipFile(path) as fmu:
            names, description = fmu.namelist(), ElementTree.fromstring(fmu.read("modelDescription.xml"))
        platforms = {name.split("/")[1] for name in names if name.startswith("binaries/") and name.count("/") >= 2}
        carried = {packing.carried_python_platform(name) for name in names} - {None}
        interfaces = [element for element in description if element.tag in ("CoSimulation", "ModelExchange")]
        assert interfaces and {element.get("needsExecutionTool") for element in interfaces} == {
            "false" if platforms <= carried else "true"}, (path, platforms, carried)


def test_a_python_without_a_shared_library_builds_fmus_without_one_and_says_so(tmp_path, monkeypatch, capsys):
    machine_needs.c_compiler("the FMU's Linux loader")
    monkeypatch.setattr(linux_python, "_shared_library", lambda: None)
    path = build(tmp_path / "SpringBlockFriction.fmu")
    with zipfile.ZipFile(path) as fmu:
        assert packing.packed_name("linux64") not in fmu.namelist()
        needs = fmu.read(DEPENDENCIES_FILE).decode()
        assert b'needsExecutionTool="true"' in fmu.read("modelDescription.xml")  # a Python must be installed
    assert f"else {build_libpython()[1]} (the build's;" in needs and "the one the FMU carries" not in needs
    assert "carries no CPython for Linux hosts without one: this Python" in capsys.readouterr().err
