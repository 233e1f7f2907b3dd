#!/usr/bin/env bash
# Builds the CMake preset "sanitize" (build-sanitize/: clang -O2, AddressSanitizer +
# UndefinedBehaviorSanitizer, every report fatal) and runs under it
#   1. every unit test (ctest over fourd_tests, two at a time);
#   2. the end-to-end test: the workflow test session (tests/workflow/session.yaml: two walks of
#      16 and 14 frames, 8 cameras of 320x240) through every stage with `fourd run`, then a
#      second `fourd run` that must find nothing to do.
# A sanitizer report or a leak aborts the process that made it, so its test (or its stage, and
# with it the driver) fails. The ctest end-to-end tests of the release build (tiny sample,
# workflow, glTF export) are left out here: they take too long under the sanitizers.
#
# usage: scripts/test_sanitizers.sh [--unit | --e2e] [ctest args...]   (default: both)
set -euo pipefail
cd "$(dirname "$0")/.."
source scripts/ccache_env.sh
what="${1:-all}"
case "$what" in
  --unit|--e2e) shift ;;
  all) ;;
  -*) ;;  # ctest arguments for both
  *) echo "usage: $0 [--unit | --e2e] [ctest args...]" >&2; exit 2 ;;
esac
export ASAN_OPTIONS=detect_leaks=1:abort_on_error=1:strict_string_checks=1
export UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1
cmake --preset sanitize > build-sanitize.cmake.log 2>&1 || { cat build-sanitize.cmake.log; exit 1; }
ninja -C build-sanitize -j"$(nproc)"

if [ "$what" != --e2e ]; then
  (cd build-sanitize && ctest --output-on-failure -j"$(nproc)" \
    -E '^(e2e_tiny_sample|gltf_export|workflow_local)$' "$@")
fi

if [ "$what" != --unit ]; then
  work=build-sanitize/e2e_session
  rm -rf "$work"
  mkdir -p "$work"
  cp tests/workflow/session.yaml "$work/session.yaml"
  echo "== end to end under the sanitizers: $work"
  build-sanitize/bin/fourd run "$work"
  test -f "$work/reports/metrics.json" || { echo "no $work/reports/metrics.json"; exit 1; }
  out=$(build-sanitize/bin/fourd run "$work" 2>&1)
  echo "$out"
  echo "$out" | grep -q "ran 0 stage(s)" || { echo "the second run reran stages"; exit 1; }
fi
