#!/usr/bin/env bash
# Build fmusim and the Feedthrough and Dahlquist FMI 2 FMUs of Reference-FMUs v0.0.39 without internet,
# from local git mirrors, into OUT (default /work/build/fmusim): OUT/fmusim, OUT/Feedthrough.fmu,
# OUT/Dahlquist.fmu. Benchmark inputs only (stickslip bench-c-hosts --fmusim OUT/fmusim).
# usage: scripts/build_fmusim.sh REFERENCE_FMUS_GIT SUNDIALS_GIT ZLIB_GIT [OUT]
# CVODE 7.3.0 and zlib 1.3.1 are the versions v0.0.39's build/build_cvode.py and build/build_zlib.py fetch;
# libxml2 is the system's (headers in /usr/include/libxml2, shared library), linked in place of the static
# library fmusim's CMakeLists expects.
set -euo pipefail
ref_git=$1 sundials_git=$2 zlib_git=$3 out=${4:-/work/build/fmusim}
work=$out/src
platform=x86_64-linux
jobs=${JOBS:-2}
rm -rf "$work" && mkdir -p "$work"
# fmusim-gui and sundials' doc hold blobs a partial mirror may lack; the build needs neither
git -C "$ref_git" archive v0.0.39 -- . ':(exclude)fmusim-gui' | tar -x -C "$work"
deps=$work/build
git -C "$zlib_git" archive --prefix=zlib-1.3.1/ v1.3.1 | tar -x -C "$deps"
git -C "$sundials_git" archive --prefix=cvode-7.3.0/ v7.3.0 -- . ':(exclude)doc' | tar -x -C "$deps"
cmake -S "$deps/zlib-1.3.1" -B "$deps/zlib-$platform/build" -DCMAKE_BUILD_TYPE=Release \
    -DCMAKE_INSTALL_PREFIX="$deps/zlib-$platform/install" > "$out/zlib.log"
cmake --build "$deps/zlib-$platform/build" -j "$jobs" --target install >> "$out/zlib.log"
cmake -S "$deps/cvode-7.3.0" -B "$deps/cvode-$platform/build" -DCMAKE_BUILD_TYPE=Release \
    -DBUILD_SHARED_LIBS=OFF -DBUILD_TESTING=OFF -DEXAMPLES_INSTALL=OFF -DEXAMPLES_ENABLE_C=OFF \
    -DSUNDIALS_ENABLE_ERROR_CHECKS=OFF -DBUILD_ARKODE=OFF -DBUILD_CVODES=OFF -DBUILD_IDA=OFF \
    -DBUILD_IDAS=OFF -DBUILD_KINSOL=OFF -DBUILD_CVODE=ON -DCMAKE_POSITION_INDEPENDENT_CODE=ON \
    -DCMAKE_INSTALL_PREFIX="$deps/cvode-$platform/install" > "$out/cvode.log"
cmake --build "$deps/cvode-$platform/build" -j "$jobs" --target install >> "$out/cvode.log"
xml=$deps/libxml2-$platform/install
mkdir -p "$xml/include" "$xml/lib"
ln -sfn /usr/include/libxml2 "$xml/include/libxml2"
ln -sfn "$(gcc -print-file-name=libxml2.so)" "$xml/lib/libxml2.a"
cmake -S "$work" -B "$work/out" -DCMAKE_BUILD_TYPE=Release -DFMI_VERSION=2 -DWITH_FMUSIM=ON > "$out/fmusim.log"
cmake --build "$work/out" -j "$jobs" >> "$out/fmusim.log"
cp "$work/out/fmusim/fmusim" "$out/fmusim"
for fmu in Feedthrough Dahlquist; do cp "$(find "$work/out" -name "$fmu.fmu" | head -1)" "$out/"; done
"$out/fmusim" --version || true
ls -l "$out"
