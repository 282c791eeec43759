#!/usr/bin/env bash
# Set up (scripts/setup.sh), install the test tools (the "test" extra), then run the whole test suite.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
echo "test: installing the test tools (pytest, hypothesis, dask, libcosimpy) into .venv"
.venv/bin/python -m pip install --quiet -e ".[test]"
.venv/bin/python -m pytest -q
