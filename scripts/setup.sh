#!/usr/bin/env bash
# Set up a fresh checkout: .venv with stickslip and its test tools (from PyPI), then build the FMU.
# Needs python3 >= 3.11 with the venv module. Safe to run again.
set -euo pipefail
cd "$(dirname "$0")/.."
python3 -m venv .venv
.venv/bin/python -m pip install --quiet -e ".[test,compile]"
.venv/bin/python build_fmu.py
