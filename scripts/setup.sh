#!/usr/bin/env bash
# Set up a fresh checkout for the main job: .venv with stickslip, its runtime dependencies and mypy (mypyc
# compiles the runtime's hot modules) from PyPI, then build the FMUs into dist/. An argument names more extras to
# install (scripts/test.sh passes "test"). Needs python3 >= 3.11 with venv. Safe to run again.
# Takes about 6 minutes on 2 busy cores, most of it mypyc compiling the runtime twice at once (for the package and
# for the FMUs), about one numba compiling the chain engine's kernels (beside the FMUs' build); with STICKSLIP_OTHER_PYTHONS=1, about 3 minutes more for each CPython newer than the build's that
# pyenv has (the FMUs' runtime compiled for it too, once per runtime; for FMUs to hand out), and about 1 minute for
# Windows's CPython 3.13 where mingw-w64 is installed. It says what it does as it goes: pip's steps in short (scripts/pip_progress.py; pip's whole log is
# .venv/pip-install.log), each C extension as it is compiled, and each FMU.
set -euo pipefail
cd "$(dirname "$0")/.."
LOG=.venv/pip-install.log
pip_failed() {
    echo "setup: pip failed; the end of its log ($LOG):" >&2
    tail -n 40 "$LOG" >&2
    exit 1
}

echo "setup: creating .venv; installing stickslip (editable), its dependencies and mypy${1:+, and the extra: $1}"
python3 -m venv .venv
# the build's requirements (pyproject.toml's build-system) go into .venv first, and pip builds stickslip there: not
# into a build environment of its own, which installed mypy a second time
BUILD_REQUIRES="$(python3 -c 'import tomllib; print(" ".join(tomllib.load(open("pyproject.toml", "rb"))["build-system"]["requires"]))')"
echo "setup: pip: installing the build requirements into .venv ($BUILD_REQUIRES)"
.venv/bin/python -m pip install -q $BUILD_REQUIRES > "$LOG" 2>&1 || pip_failed
if ! PYTHONUNBUFFERED=1 .venv/bin/python -m pip install -v --no-build-isolation -e ".[compile${1:+,$1}]" 2>&1 | tee "$LOG" \
        | python3 -u scripts/pip_progress.py; then
    pip_failed
fi
# the FMUs' generationDateAndTime and the dates of their files: the last commit's time, unless set (reproducible builds)
if [ -z "${SOURCE_DATE_EPOCH:-}" ] && git rev-parse --git-dir >/dev/null 2>&1; then
    SOURCE_DATE_EPOCH="$(git log -1 --format=%ct)" && export SOURCE_DATE_EPOCH
fi
# with STICKSLIP_OTHER_PYTHONS=1: the FMUs' runtime compiled for pyenv's newer CPythons too, where the machine has
# them, and for CPython 3.13 on Windows with mingw-w64 (each in a venv of its own, .venv-pythons/; skipped, saying
# so, where it cannot be made): the FMUs then carry those compiled files as well
if [ "${STICKSLIP_OTHER_PYTHONS:-0}" = 1 ]; then
    echo "setup: compiling the FMUs' runtime for the newer CPython versions pyenv has (scripts/other_pythons.py compile)"
    .venv/bin/python scripts/other_pythons.py compile | sed 's/^other pythons: /setup: /' \
        || echo "setup: compiling for the other CPython versions failed; the FMUs carry the runtime compiled for this one"
fi
# the chain engine's kernels compiled once into numba's cache (about a minute), so that no first chain run, and no
# test process, waits for them (the test processes would each compile them at once); on one core while the FMUs
# are built on the other
echo "setup: compiling the chain engine's kernels (numba, cached on disk), beside the FMUs' build"
.venv/bin/python -c "from stickslip.chain.engine import warm_up; print(f'setup: chain engine compiled in {warm_up():.0f} s')" &
KERNELS=$!
echo "setup: building the FMUs (FMI 2, FMI 3) into dist/"
.venv/bin/python build_fmu.py | sed 's/^/setup: FMU built at /'  # one line per FMU (FMI 2, FMI 3)
wait "$KERNELS"
