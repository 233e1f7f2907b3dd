#!/usr/bin/env bash
# Builds the CMake preset "sanitize" (build-sanitize/: clang -O2, AddressSanitizer +
# UndefinedBehaviorSanitizer, every report fatal) and runs under it
#   1. every unit test: fourd_tests split into one GoogleTest shard per core, each shard one
#      process, so that the tests which build the synthetic performer (cached per process) build
#      it once per shard rather than once per test (ctest runs them the same way,
#      tests/CMakeLists.txt);
#   2. the end-to-end test: the workflow test session (tests/workflow/session.yaml: two walks of
#      11 and 10 frames, 8 cameras of 320x240) through every stage with `fourd run`, then a
#      second `fourd run` that must find nothing to do.
# A sanitizer report or a leak aborts the process that made it, so its shard (whose log names
# the test that was running) or its stage, and with it the driver, fails. The ctest end-to-end
# tests of the release build (tiny sample, workflow, glTF export) are left out here: they take
# too long under the sanitizers.
#
# usage: scripts/test_sanitizers.sh [--unit | --e2e] [fourd_tests args, e.g. --gtest_filter=...]
#        (default: both)
set -euo pipefail
cd "$(dirname "$0")/.."
source scripts/ccache_env.sh
what="${1:-all}"
case "$what" in
  --unit|--e2e) shift ;;
  all) ;;
  -*) ;;  # fourd_tests arguments
  *) echo "usage: $0 [--unit | --e2e] [fourd_tests args...]" >&2; exit 2 ;;
esac
export ASAN_OPTIONS=detect_leaks=1:abort_on_error=1:strict_string_checks=1
export UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1
cmake --preset sanitize > build-sanitize.cmake.log 2>&1 || { cat build-sanitize.cmake.log; exit 1; }
ninja -C build-sanitize -j"$(nproc)"

if [ "$what" != --e2e ]; then
  # Run where ctest would run them (the tests' relative paths), each shard logging to its file;
  # a shard that hangs is stopped (ctest stopped a test after 15 minutes).
  shards=$(nproc)
  pids=()
  for ((i = 0; i < shards; ++i)); do
    log="$PWD/build-sanitize/unit_shard_$i.log"
    (cd build-sanitize/tests && GTEST_TOTAL_SHARDS=$shards GTEST_SHARD_INDEX=$i \
      timeout 2400 ../bin/fourd_tests "$@" > "$log" 2>&1) &
    pids+=($!)
  done
  failed=0
  for ((i = 0; i < shards; ++i)); do
    log="build-sanitize/unit_shard_$i.log"
    if wait "${pids[$i]}"; then
      echo "unit tests, shard $((i + 1)) of $shards: $(grep -E '^\[  (PASSED|SKIPPED) +\] [0-9]+ tests?[.,]' "$log" | sed 's/, listed below://' | tr '\n' ' ')"
    else
      failed=1
      echo "unit tests, shard $((i + 1)) of $shards FAILED ($log):"
      tail -n 60 "$log"
    fi
  done
  [ "$failed" = 0 ] || exit 1
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
  grep -q "ran 0 stage(s)" <<< "$out" || { echo "the second run reran stages"; exit 1; }
fi
