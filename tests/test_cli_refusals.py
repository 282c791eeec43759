"""What ``stickslip run`` and ``stickslip system run``/``ssp`` refuse before any simulation work, as a user meets
it: a child process, one line on stderr naming what is wrong (no traceback), exit status 1, no output written.
(A ``--step`` out of range, a usage error: tests/test_system_engines.py.)"""

import subprocess

import pytest

from stickslip.fmu.coupling import ensure_coupling_fmu

from cli_child import STICKSLIP
from scenario_texts import VALID
from test_systems import CHAIN2

#: seconds a refusal may take: it comes before any simulation (the child's start included, on a loaded machine)
REFUSED_WITHIN = 60


@pytest.fixture(scope="module")
def coupling_path():
    """ChainCoupling.fmu: an FMU, not the block's."""
    return ensure_coupling_fmu()


def refused(args, tmp_path):
    """The one line ``stickslip args`` prints on stderr when it refuses them (exit status 1, nothing in ``out``)."""
    proc = subprocess.run([*STICKSLIP, *args], capture_output=True, text=True, timeout=REFUSED_WITHIN)
    assert proc.returncode == 1, proc.stderr
    assert "Traceback" not in proc.stderr
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1, proc.stderr
    out = tmp_path / "out"
    assert not out.exists() or not list(out.iterdir())
    return lines[0]


def scenario(tmp_path, *changes):
    path = tmp_path / "case.toml"
    text = VALID
    for old, new in changes:
        assert old in text
        text = text.replace(old, new)
    path.write_text(text)
    return path


@pytest.mark.parametrize("fmu, message", [
    ("/etc/passwd", "stickslip run: /etc/passwd: not an FMU (BadZipFile: File is not a zip file)"),
    ("missing.fmu", "stickslip run: missing.fmu: cannot read the FMU: No such file or directory"),
    ("coupling", "the FMU ChainCoupling has no variable 'v': it is not a SpringBlockFriction FMU"),
])
def test_run_refuses_an_fmu_that_is_not_the_block(tmp_path, fmu, message, coupling_path):
    fmu = str(coupling_path) if fmu == "coupling" else fmu
    line = refused(["run", str(scenario(tmp_path)), "--fmu", fmu, "--out", str(tmp_path / "out")], tmp_path)
    assert line.endswith(message)


@pytest.mark.parametrize("fmu, message", [
    ("/etc/passwd", "/etc/passwd: not an FMU (BadZipFile: File is not a zip file)"),
    ("coupling", "the FMU ChainCoupling has no variable 'M': it is not a SpringBlockFriction FMU"),
])
@pytest.mark.parametrize("command", ["run", "ssp"])
def test_system_commands_refuse_an_fmu_that_is_not_the_block(tmp_path, fmu, message, command, coupling_path):
    fmu = str(coupling_path) if fmu == "coupling" else fmu
    master = ["--master", "zoh", "--quiet"] if command == "run" else []
    line = refused(["system", command, str(CHAIN2), "--fmu", fmu, "--out", str(tmp_path / "out"), *master],
                   tmp_path)
    assert line.startswith("stickslip system: ") and line.endswith(message)


@pytest.mark.parametrize("args", [["run", "SCENARIO"], ["system", "run", str(CHAIN2), "--master", "me", "--quiet"],
                                  ["system", "ssp", str(CHAIN2)]])
def test_an_output_folder_that_cannot_be_made_is_refused_first(tmp_path, args):
    """``--out`` under a file: named before anything runs (it used to fail after the whole simulation)."""
    (tmp_path / "file").write_text("")
    args = [str(scenario(tmp_path)) if a == "SCENARIO" else a for a in args]
    line = refused([*args, "--out", str(tmp_path / "file" / "out")], tmp_path)
    assert line.endswith(f"--out {tmp_path / 'file' / 'out'}: cannot make or use the folder: Not a directory")


@pytest.mark.parametrize("changes, message", [
    ([("output_interval = 0.1", "output_interval = 1e-300")],
     "key 'simulation.output_interval': stop_time / output_interval = 1e+301 output points: allowed is at most 1e+06"),
    ([("stop_time = 10.0", "stop_time = 1e9"), ("output_interval = 0.1", "output_interval = 0.001")],
     "key 'simulation.output_interval': stop_time / output_interval = 1e+12 output points"),
    ([("stop_time = 10.0", "stop_time = 1e7"), ("output_interval = 0.1", "output_interval = 100.0")],
     "key 'simulation.stop_time': the run is 1.59e+06 free periods long (stop_time over the shortest free period "
     "6.28 s): allowed is at most 100000"),
    ([("stop_time = 10.0", "stop_time = 1e12"), ("output_interval = 0.1", "output_interval = 1e7")],
     "key 'simulation.stop_time': the run is 1.59e+11 free periods long"),
    ([('name = "case"', f'name = "{"a" * 300}"')], "key 'name': expected at most 100 letters, digits"),
])
def test_run_refuses_a_scenario_that_cannot_finish_or_be_written(tmp_path, changes, message):
    path = scenario(tmp_path, *changes)
    line = refused(["run", str(path), "--out", str(tmp_path / "out")], tmp_path)
    assert line.startswith(f"stickslip run: {path}: ") and message in line
