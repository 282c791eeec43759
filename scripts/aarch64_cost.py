"""Start-up and per-step cost of the FMI 3 FMU's aarch64 Linux binaries under QEMU's user-mode emulator, side by side
with its x86_64 binaries: the project's FMI 3 C host (``run`` mode, the elmer-fig3 scene's block, 0.1 s steps) built
for aarch64 in an aarch64 root that holds glibc alone (``stickslip.hosts.c_host.aarch64_root``, chroot: run as root)
and built for x86_64 on this machine, with the runtime compiled (the build's) and with its sources
(``STICKSLIP_PURE_PYTHON=1``, what the aarch64 CPython runs). Each case runs a fresh process of one step (start-up:
Python's start, the imports, one step) and of 30,000 steps, the cases alternating round after round; prints the
medians, the cost per step (the long run less the short one, over the steps) and the ratios to x86_64.

    python scripts/aarch64_cost.py [--fmu dist/SpringBlockFriction-fmi3.fmu] [--rounds 7]
"""

import argparse
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
import zipfile
from pathlib import Path

from stickslip.hosts.c_host import aarch64_root, compile_host, host_command, host_env
from stickslip.suite.scenario import load_scenario

REPO = Path(__file__).resolve().parents[1]
SCENE = REPO / "scenarios" / "elmer-fig3-v0.1.toml"
STEP, STEPS = 0.1, 30000
#: case: (aarch64 under QEMU?, environment)
CASES = {"aarch64 under QEMU": (True, {}), "x86_64, compiled": (False, {}),
         "x86_64, sources": (False, {"STICKSLIP_PURE_PYTHON": "1"})}


def seconds(command, env):
    """Wall time of one run of ``command`` (a list); exits naming it if it fails."""
    start = time.perf_counter()
    run = subprocess.run(command, capture_output=True, text=True, env=host_env(env))
    if run.returncode != 0:
        sys.exit(f"{command[0]} failed ({run.returncode}): {run.stderr[-1000:]}")
    return time.perf_counter() - start


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--fmu", type=Path, default=REPO / "dist" / "SpringBlockFriction-fmi3.fmu")
    parser.add_argument("--rounds", type=int, default=7)
    args = parser.parse_args()
    emulator = shutil.which("qemu-aarch64-static")
    if emulator is None:
        sys.exit("needs qemu-aarch64-static (Debian's qemu-user-static; scripts/test.sh installs it)")
    start = load_scenario(SCENE).start_values()
    with tempfile.TemporaryDirectory(prefix="sbf_aarch64_cost_") as tmp:
        root, native = Path(tmp) / "root", Path(tmp) / "native"
        for folder in (root / "fmu", native / "fmu"):
            zipfile.ZipFile(args.fmu).extractall(folder)
        if not (root / "fmu" / "binaries" / "aarch64-linux").is_dir():
            sys.exit(f"{args.fmu} has no aarch64 binaries (its build said why)")
        wrapper = aarch64_root(root, emulator)
        hosts = {True: compile_host(root, 3, aarch64=True), False: compile_host(native, 3)}
        times = {(case, stop): [] for case in CASES for stop in (STEP, STEP * STEPS)}
        for round_ in range(args.rounds):
            for (case, stop), found in times.items():
                emulated, env = CASES[case]
                command = host_command(hosts[emulated], (root if emulated else native) / "fmu", "run", stop, STEP,
                                       start, root=root if emulated else None)
                found.append(seconds([*wrapper, *command] if emulated else command, env))
            print(f"round {round_ + 1}/{args.rounds} done", file=sys.stderr, flush=True)
    medians = {key: statistics.median(found) for key, found in times.items()}
    per_step = {case: (medians[case, STEP * STEPS] - medians[case, STEP]) / STEPS * 1e6 for case in CASES}
    reference = "x86_64, compiled"
    for case in CASES:
        print(f"{case:20s} start-up {medians[case, STEP]:6.3f} s ({medians[case, STEP] / medians[reference, STEP]:5.1f}"
              f" x)  per step {per_step[case]:7.1f} us ({per_step[case] / per_step[reference]:5.1f} x, "
              f"{per_step[case] / per_step['x86_64, sources']:5.1f} x the sources')")


if __name__ == "__main__":
    main()
