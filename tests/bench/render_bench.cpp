// The virtual studio renderer: one 640x480 view of a ~5k-vertex textured sphere with the
// default studio (soft shadows, 4-sample anti-aliasing on edges, noise), on one thread and on
// all threads; and the per-frame BVH build.
#include <benchmark/benchmark.h>
#include <tbb/global_control.h>
#include <tbb/info.h>

#include "stages/synth/render.h"
#include "tests/synth/uv_sphere.h"

namespace fourd::synth {
namespace {

// 51 x 101 = 5151 vertices, standing in the middle of the capture volume.
Mesh bench_sphere() {
  return test::make_uv_sphere(Eigen::Vector3f(0.2f, 0.1f, 0.9f), 0.5f, 50, 100);
}

void render_view(benchmark::State& state, int threads) {
  tbb::global_control limit(tbb::global_control::max_allowed_parallelism, threads);
  StudioRenderer renderer{StudioOptions{}};
  renderer.set_performer(bench_sphere(), test::checker_texture(512, 16));
  RigOptions rig;
  rig.k1 = -0.05;
  rig.k2 = 0.01;
  const Camera camera = make_rig(rig)[0];
  RenderStats stats;
  std::uint64_t seed = 0;
  for (auto _ : state) {
    RenderedView view = renderer.render(camera, ++seed);
    stats = view.stats;
    benchmark::DoNotOptimize(view.image.data);
  }
  const double rays = static_cast<double>(stats.camera_rays + stats.shadow_rays);
  state.counters["rays/s"] =
      benchmark::Counter(rays, benchmark::Counter::kIsIterationInvariantRate);
  state.counters["camera_rays"] = static_cast<double>(stats.camera_rays);
  state.counters["shadow_rays"] = static_cast<double>(stats.shadow_rays);
  state.counters["aa_pixels"] = static_cast<double>(stats.supersampled_pixels);
}

void BM_RenderView640x480OneThread(benchmark::State& state) { render_view(state, 1); }
BENCHMARK(BM_RenderView640x480OneThread)->Unit(benchmark::kMillisecond)->UseRealTime();

void BM_RenderView640x480AllThreads(benchmark::State& state) {
  render_view(state, tbb::info::default_concurrency());
}
BENCHMARK(BM_RenderView640x480AllThreads)->Unit(benchmark::kMillisecond)->UseRealTime();

// Per frame the posed mesh changes: set_performer rebuilds the BVH and the mip pyramid.
void BM_SetPerformer(benchmark::State& state) {
  tbb::global_control limit(tbb::global_control::max_allowed_parallelism, 1);
  StudioRenderer renderer{StudioOptions{}};
  const Mesh sphere = bench_sphere();
  const cv::Mat texture = test::checker_texture(1024, 32);
  for (auto _ : state) renderer.set_performer(sphere, texture);
}
BENCHMARK(BM_SetPerformer)->Unit(benchmark::kMillisecond);

}  // namespace
}  // namespace fourd::synth
