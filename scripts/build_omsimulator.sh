#!/usr/bin/env bash
# Build OMSimulator (its command-line binary and, unless BINARY_ONLY=1, its Python package) without internet, from
# local git mirrors, into OUT (default /work/build/oms): OUT/install/bin/OMSimulator. By-hand runs only
# (scripts/omsimulator_chain.py, scripts/omsimulator_me.py); CI cannot build it (its PyPI sdist downloads binaries).
# usage: [JOBS=N] [BINARY_ONLY=1] scripts/build_omsimulator.sh OMSIMULATOR_GIT OMSIMULATOR_3RDPARTY_GIT SUNDIALS_GIT
#            [OUT [SUNDIALS_PREFIX]]
# OMSimulator's HEAD (after its "Update SUNDIALS to 7.8.0") calls the SUNDIALS 7 API (SUNContext_Create with
# SUN_COMM_NULL, SUNContext_PushErrHandler with a SUNErrCode handler), but the 3rdParty mirror's HEAD still
# ships sundials-5.4.0 (the 3rdParty commit OMSimulator pins is not in the mirror). So SUNDIALS v7.5.0 (the
# newest tag in the mirror; OMSimulator pins 7.8.0) is built apart (CVODE, KINSOL; static, PIC) into
# SUNDIALS_PREFIX and 3rdParty/CMakeLists.txt's SUNDIALS block is replaced by a find_package of it.
# An existing OUT is reused (only the edit is redone), so a stopped build resumes.
set -euo pipefail
oms_git=$1 third_git=$2 sundials_git=$3 out=${4:-/work/build/oms} prefix=${5:-/work/build/sundials-install}
jobs=${JOBS:-2}
sundials_tag=v7.5.0
if [ ! -f "$out/CMakeLists.txt" ]; then
    mkdir -p "$out/3rdParty"
    # the testsuite's reference results and the 3rdParty docs hold blobs a partial mirror may lack
    git -C "$oms_git" archive HEAD -- . ':(exclude)testsuite' | tar -x -C "$out"
    git -C "$third_git" archive HEAD | tar -x -C "$out/3rdParty"
fi
if [ ! -f "$prefix/lib/cmake/sundials/SUNDIALSConfig.cmake" ]; then
    src=$(dirname "$prefix")/sundials-src
    rm -rf "$src" && mkdir -p "$src"
    git -C "$sundials_git" archive --prefix=sundials/ "$sundials_tag" -- . ':(exclude)doc' ':(exclude)examples' \
        ':(exclude)test' | tar -x -C "$src"
    cmake -S "$src/sundials" -B "$src/build" -DCMAKE_BUILD_TYPE=Release -DBUILD_SHARED_LIBS=OFF \
        -DBUILD_STATIC_LIBS=ON -DBUILD_TESTING=OFF -DEXAMPLES_INSTALL=OFF -DEXAMPLES_ENABLE_C=OFF \
        -DEXAMPLES_ENABLE_CXX=OFF -DBUILD_ARKODE=OFF -DBUILD_CVODES=OFF -DBUILD_IDA=OFF -DBUILD_IDAS=OFF \
        -DBUILD_CVODE=ON -DBUILD_KINSOL=ON -DCMAKE_POSITION_INDEPENDENT_CODE=ON \
        -DCMAKE_INSTALL_PREFIX="$prefix" > "$src/cmake.log"
    cmake --build "$src/build" -j "$jobs" --target install > "$src/build.log"
fi
# 3rdParty's SUNDIALS block (lines from "## Sundials" up to the first zlib line) becomes the installed
# SUNDIALS 7, its targets made global so that src/OMSimulatorLib sees the aliases.
python3 - "$out/3rdParty/CMakeLists.txt" <<'EOF'
import re, sys
path = sys.argv[1]
text = open(path).read()
block = """## Sundials: SUNDIALS 7, installed apart (scripts/build_omsimulator.sh)
find_package(SUNDIALS 7 REQUIRED CONFIG)
foreach(lib core cvode kinsol)
  set_target_properties(SUNDIALS::${lib}_static PROPERTIES IMPORTED_GLOBAL TRUE)
endforeach()
add_library(oms::3rd::sundials::cvode ALIAS SUNDIALS::cvode_static)
add_library(oms::3rd::sundials::kinsol ALIAS SUNDIALS::kinsol_static)

"""
text = re.sub(r"## Sundials\n.*?(?=#+\n## zlib)", lambda _: block, text, count=1, flags=re.S)
text = re.sub(r"\nadd_library\(oms::3rd::sundials::\w+ ALIAS sundials_\w+_static\)", "", text)
open(path, "w").write(text)
EOF
# OMSimulator's bug: SystemWC::initialize sets a local mav_doDoubleStep that shadows the member, which stays
# uninitialized, so oms-mav may step as oms-mav2 and fail ("We shouldn't be doing double stepping ..."): set the member.
sed -i 's/^\( *\)bool mav_doDoubleStep = (solverMethod/\1mav_doDoubleStep = (solverMethod/' \
    "$out/src/OMSimulatorLib/SystemWC.cpp"
cmake -S "$out" -B "$out/build" -DCMAKE_BUILD_TYPE=Release -DCMAKE_PREFIX_PATH="$prefix" \
    -DCMAKE_INSTALL_PREFIX="$out/install" > "$out/cmake.log"
if [ -n "${BINARY_ONLY:-}" ]; then
    # the command-line binary alone: it links the static library, so the shared one (for the Python package) and
    # the GUI are left out, about half the compile
    nice cmake --build "$out/build" -j "$jobs" --target OMSimulator > "$out/build.log"
    install -D "$out/build/src/OMSimulator/OMSimulator" "$out/install/bin/OMSimulator"
else
    nice cmake --build "$out/build" -j "$jobs" --target install > "$out/build.log"
fi
"$out/install/bin/OMSimulator" --version
