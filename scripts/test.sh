#!/usr/bin/env bash
# Set up (scripts/setup.sh) with the test tools (the "test" extra: pytest, hypothesis, dask, libcosimpy), then run
# the whole test suite.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh test
.venv/bin/python -m pytest -q
