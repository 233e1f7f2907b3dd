#!/usr/bin/env bash
# Runs the unit tests built with AddressSanitizer + UndefinedBehaviorSanitizer; any sanitizer
# report (or leak) fails the run.
#
# usage: scripts/test_sanitizers.sh [--all] [gtest args...]
# By default (as CI runs it) it uses the tree of the CMake preset "fuzz" (build-fuzz/, clang,
# shared with the fuzz targets of tests/fuzz/run_fuzz.sh so CI compiles the sanitized code
# once), whose test program holds the topics that parse files or run in the runtime: core
# (meshes, cameras, COLMAP, config, binary formats, files), driver, runtime, timewarp,
# motionspace, graph and the fuzz targets' seeds and regression inputs. The CGAL/Embree-heavy
# stages (synth's renderer, segment, reconstruct, align, validate) are left out: a sanitizer
# build of everything takes longer than CI allows on two cores.
# --all uses the preset "asan" (build-asan/, g++): every topic, the stage executables, and the
# end-to-end test, through ctest.
set -euo pipefail
cd "$(dirname "$0")/.."
source scripts/ccache_env.sh
export ASAN_OPTIONS=detect_leaks=1:abort_on_error=1:strict_string_checks=1
export UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1
if [ "${1:-}" = "--all" ]; then
  shift
  cmake --preset asan > build-asan.cmake.log 2>&1 || { cat build-asan.cmake.log; exit 1; }
  ninja -C build-asan -j"$(nproc)"
  cd build-asan && ctest --output-on-failure -j"$(nproc)" "$@"
else
  cmake --preset fuzz > build-fuzz.cmake.log 2>&1 || { cat build-fuzz.cmake.log; exit 1; }
  ninja -C build-fuzz -j"$(nproc)" fourd_tests
  build-fuzz/bin/fourd_tests "$@"
fi
