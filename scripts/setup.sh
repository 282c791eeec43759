#!/usr/bin/env bash
# Set up a fresh checkout for the main job: .venv with stickslip, its runtime dependencies and mypy (mypyc
# compiles the runtime's hot modules) from PyPI, then build the FMUs. An argument names more extras to install
# (scripts/test.sh passes "test"). Needs python3 >= 3.11 with venv. Safe to run again.
set -euo pipefail
cd "$(dirname "$0")/.."
echo "setup: installing stickslip and its runtime dependencies${1:+ (and the extra: $1)} into .venv"
python3 -m venv .venv
.venv/bin/python -m pip install --quiet -e ".[compile${1:+,$1}]"
.venv/bin/python build_fmu.py | sed 's/^/setup: FMU built at /'  # one line per FMU (FMI 2, FMI 3)
