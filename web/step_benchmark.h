#pragma once
// The runtime step benchmark of the web player (docs/web.md), built into the WebAssembly module
// and natively (tests/web/step_bench.cpp), so the browser's and the native step times come from
// the same code.
#include <cstddef>

#include "runtime/asset.h"

namespace fourd::web {

// Wall-clock time of one Character::step at a fixed motion-time step, walking under the
// controller at the locomotion space's middle speed with a heading change every second (so
// transitions and searches are part of it), after an untimed run of the same steps. The steps
// are timed in `rounds` runs from the same start: mean_us is the mean step of the fastest run,
// the one least disturbed by other processes on a shared machine (the same code, so the same
// rule, on both sides of the browser/native comparison), median_us that of the median run.
// With evict_bytes > 0 a buffer of that size is written between two steps, untimed, and each
// step is timed alone: every step starts with cold caches, as the one step of a frame does in
// live play after the frame's drawing and whatever else ran.
struct StepBenchmark {
  int steps = 0;  // per run
  int rounds = 0;
  std::size_t evict_bytes = 0;
  int vertices = 0;
  double mean_us = 0;
  double median_us = 0;
  double total_ms = 0;  // all timed runs
};
StepBenchmark benchmark_steps(const Asset& asset, int steps, double dt, int rounds = 5,
                              std::size_t evict_bytes = 0);

}  // namespace fourd::web
