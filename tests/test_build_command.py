"""The build commands as a user types them: ``python build_fmu.py --out DIR`` and ``stickslip build-fmu --out DIR``
(the alias of ``stickslip build``) build both FMUs (and the chain's coupling FMU) into DIR, print their paths, give the same bytes as the
session's builds, and a second call leaves the current files alone. Each runs in a child process from another
working folder; the runtime's compile is cached, so a call takes a few seconds."""

import filecmp
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
COMMANDS = {
    "build_fmu.py": [sys.executable, str(ROOT / "build_fmu.py")],
    "stickslip build-fmu": [str(Path(sys.executable).parent / "stickslip"), "build-fmu"],
}


def _build(command, out, cwd):
    run = subprocess.run([*command, "--out", str(out)], cwd=cwd, capture_output=True, text=True, timeout=600)
    assert run.returncode == 0, run.stderr
    return run.stdout.split()


@pytest.mark.parametrize("name", COMMANDS)
def test_the_command_builds_both_fmus_into_the_folder(name, tmp_path, fmu_path, fmu3_path):
    out = tmp_path / "fmus"
    printed = _build(COMMANDS[name], out, cwd=tmp_path)
    built_paths = [out / fmu_path.name, out / fmu3_path.name, out / "ChainCoupling.fmu"]  # and a chain's coupling
    assert printed == [str(path) for path in built_paths]
    for built, session in ((out / fmu_path.name, fmu_path), (out / fmu3_path.name, fmu3_path)):
        # filecmp: the same check, without pytest's diff of two FMUs' bytes (minutes) when it fails
        assert filecmp.cmp(built, session, shallow=False), f"{name} built other bytes than the session's build"
    stamps = [path.stat().st_mtime_ns for path in built_paths]
    assert _build(COMMANDS[name], out, cwd=tmp_path) == printed
    assert [path.stat().st_mtime_ns for path in built_paths] == stamps, "current FMUs were built again"
