#!/usr/bin/env bash
# Set up a fresh checkout for the main job: .venv with stickslip and its runtime dependencies (from PyPI),
# then build the FMUs. The test tools are installed by scripts/test.sh. Needs python3 >= 3.11 with venv.
# Safe to run again.
set -euo pipefail
cd "$(dirname "$0")/.."
echo "setup: installing stickslip and its runtime dependencies into .venv"
python3 -m venv .venv
.venv/bin/python -m pip install --quiet -e .
.venv/bin/python build_fmu.py | sed 's/^/setup: FMU built at /'  # one line per FMU (FMI 2, FMI 3)
