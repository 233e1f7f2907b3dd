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

// Milliseconds the steps took; with `evict`, its bytes are written between two steps (not timed)
// so that every step starts with cold caches, as one step a frame does in a live player.
double timed_steps(const Asset& asset, int steps, double dt, std::vector<char>* evict = nullptr) {
  using Clock = std::chrono::steady_clock;
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
  Clock::duration timed{};
  auto t0 = Clock::now();
  for (int k = 0; k < steps; ++k) {
    if (evict) {
      std::fill(evict->begin(), evict->end(), static_cast<char>(k));
      t0 = Clock::now();
    }
    if (locomotion >= 0 && k % per_second == per_second - 1) {
      controller.walk(speed, ((k / per_second) % 2 ? -40 : 40) * kDeg);
    }
    character.step(dt);
    if (evict) timed += Clock::now() - t0;
  }
  if (!evict) timed = Clock::now() - t0;
  return std::chrono::duration<double, std::milli>(timed).count();
}

}  // namespace

StepBenchmark benchmark_steps(const Asset& asset, int steps, double dt, int rounds,
                              std::size_t evict_bytes) {
  // A first, untimed run: a browser compiles WebAssembly with a baseline compiler first and
  // optimises the functions that turn out hot while they run (the first run there is about 4x
  // slower); natively it warms the caches.
  timed_steps(asset, steps, dt);
  StepBenchmark b;
  b.steps = steps;
  b.rounds = std::max(1, rounds);
  b.evict_bytes = evict_bytes;
  b.vertices = asset.graph.spaces.front().motion.blend.num_vertices;
  std::vector<char> evict(evict_bytes);
  std::vector<double> ms(b.rounds);
  for (double& m : ms) m = timed_steps(asset, steps, dt, evict_bytes > 0 ? &evict : nullptr);
  for (double m : ms) b.total_ms += m;
  std::sort(ms.begin(), ms.end());
  const double per_step = steps > 0 ? 1e3 / steps : 0;
  b.mean_us = ms.front() * per_step;
  b.median_us = ms[ms.size() / 2] * per_step;
  return b;
}

}  // namespace fourd::web
