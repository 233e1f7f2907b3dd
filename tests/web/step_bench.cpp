// The web player's runtime step benchmark (web/step_benchmark.h), native: the reference the
// browser's step time is compared with (tests/e2e/web_player.sh).
// usage: web_step_bench ASSET [STEPS] [DT] [EVICT_MB]   (EVICT_MB: cold caches before each step)
// prints {"steps", "rounds", "evict_bytes", "vertices", "mean_us", "median_us", "total_ms"}
#include <fmt/format.h>

#include <exception>
#include <string>

#include "pipeline/core/error.h"
#include "runtime/asset.h"
#include "web/step_benchmark.h"

int main(int argc, char** argv) {
  if (argc < 2 || argc > 5) {
    fmt::print(stderr, "usage: web_step_bench ASSET [STEPS] [DT] [EVICT_MB]\n");
    return fourd::kExitUsage;
  }
  try {
    const fourd::Asset asset = fourd::load_asset(argv[1]);
    const int steps = argc > 2 ? std::stoi(argv[2]) : 3000;
    const double dt = argc > 3 ? std::stod(argv[3]) : 1.0 / 60;
    const double evict_mb = argc > 4 ? std::stod(argv[4]) : 0;
    const fourd::web::StepBenchmark b = fourd::web::benchmark_steps(
        asset, steps, dt, 5, static_cast<std::size_t>(evict_mb * (1 << 20)));
    fmt::print(
        "{{\"steps\": {}, \"rounds\": {}, \"evict_bytes\": {}, \"vertices\": {}, \"mean_us\": "
        "{:.3f}, \"median_us\": {:.3f}, \"total_ms\": {:.3f}}}\n",
        b.steps, b.rounds, b.evict_bytes, b.vertices, b.mean_us, b.median_us, b.total_ms);
  } catch (const std::exception& e) {
    fmt::print(stderr, "web_step_bench: {}\n", e.what());
    return fourd::kExitFailure;
  }
  return fourd::kExitOk;
}
