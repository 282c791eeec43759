"""Every script in examples/ runs as it stands, on its small setting (``--quick``), and draws its figure; the
examples' README lists each of them."""

import re
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
EXAMPLES = sorted((REPO / "examples").glob("*.py"))
#: the examples that run an FMU take the session's build (``--fmu``) rather than building one into dist/
FMU_FIXTURES = {"fmu_fmpy": "fmu_path", "chain_spacetime": "fmu3_path"}
PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"


def test_there_are_examples():
    assert {"bifurcation_fig3", "three_regimes", "aging_map", "fmu_fmpy", "chain_spacetime",
            "bk_size_distribution"} <= {script.stem for script in EXAMPLES}


@pytest.mark.parametrize("script", EXAMPLES, ids=lambda script: script.stem)
def test_example_runs_and_writes_its_figure(script, tmp_path, request):
    command = [sys.executable, str(script.relative_to(REPO)), "--quick", "--out", str(tmp_path)]
    if script.stem in FMU_FIXTURES:
        command += ["--fmu", str(request.getfixturevalue(FMU_FIXTURES[script.stem]))]
    run = subprocess.run(command, cwd=REPO, capture_output=True, text=True, timeout=600)
    assert run.returncode == 0, f"{script.name} exited with {run.returncode}:\n{run.stderr[-4000:]}"
    figure = tmp_path / f"{script.stem}.png"
    assert figure.is_file(), f"{script.name} wrote no {figure.name}; its output:\n{run.stdout[-2000:]}"
    assert figure.stat().st_size > 10_000 and figure.read_bytes()[:8] == PNG_SIGNATURE
    assert f"written to {figure}" in run.stdout
    assert not re.search(r"\w+Warning\b", run.stderr), f"{script.name} let a warning through:\n{run.stderr}"


@pytest.mark.parametrize("script", EXAMPLES, ids=lambda script: script.stem)
def test_example_says_how_to_run_it(script):
    """The docstring at the top gives the command line with the small setting, and the examples' README lists
    the script."""
    text = script.read_text()
    assert f"python examples/{script.name} [--quick]" in text and "--quick:" in text
    assert f"[{script.name}]({script.name})" in (REPO / "examples" / "README.md").read_text()
