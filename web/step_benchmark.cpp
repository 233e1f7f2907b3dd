#include "web/step_benchmark.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <numbers>
#include <vector>

#include "runtime/character.h"
#include "runtime/controller.h"

namespace fourd::web {

namespace {

constexpr double kDeg = std::numbers::pi / 180;

double timed_steps(const Asset& asset, int steps, double dt) {
  const MotionGraph& graph = asset.graph;
  Character character(graph, asset.transitions);
  Controller controller(character);
  const int locomotion = graph.find_space(ControllerOptions{}.locomotion_space);
  const int start = locomotion >= 0 ? locomotion : 0;
  const GraphSpace& g = graph.spaces[start];
  const double speed = 0.5 * (g.parameter_min() + g.parameter_max());
  character.reset(start, speed);
  if (locomotion >= 0) controller.walk(speed, 0);
  character.step(0);
  const int per_second = std::max(1, static_cast<int>(std::lround(1 / dt)));
  const auto t0 = std::chrono::steady_clock::now();
  for (int k = 0; k < steps; ++k) {
    if (locomotion >= 0 && k % per_second == per_second - 1) {
      controller.walk(speed, ((k / per_second) % 2 ? -40 : 40) * kDeg);
    }
    character.step(dt);
  }
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
}

}  // namespace

StepBenchmark benchmark_steps(const Asset& asset, int steps, double dt, int rounds) {
  // A first, untimed run: a browser compiles WebAssembly with a baseline compiler first and
  // optimises the functions that turn out hot while they run (the first run there is about 4x
  // slower); natively it warms the caches.
  timed_steps(asset, steps, dt);
  StepBenchmark b;
  b.steps = steps;
  b.rounds = std::max(1, rounds);
  b.vertices = asset.graph.spaces.front().motion.blend.num_vertices;
  std::vector<double> ms(b.rounds);
  for (double& m : ms) m = timed_steps(asset, steps, dt);
  for (double m : ms) b.total_ms += m;
  std::sort(ms.begin(), ms.end());
  const double per_step = steps > 0 ? 1e3 / steps : 0;
  b.mean_us = ms.front() * per_step;
  b.median_us = ms[ms.size() / 2] * per_step;
  return b;
}

}  // namespace fourd::web
