// The CPU texture blend of the textured runtime (blend_texture_image, runtime/textures.h):
// the frame's key textures (8-bit BGR) mixed with their weights into a kept image, for
// renderers without shaders. Arguments: texture side (256, 512, 1024) and number of images
// blended: 2 (one take between two key phases), 4 (two takes), 8 (a cross-fade of two such
// blends).
//
//   fourd_bench --benchmark_filter=BM_TextureBlend
//
// Measured 2026-11-25 (2-core shared VM, loaded; Release, CPU time per blend):
//   images blended          2         4         8
//   256 x 256            0.15 ms   0.22 ms   0.46 ms
//   512 x 512            0.64 ms   0.90 ms   2.0 ms
//   1024 x 1024          2.7 ms    3.8 ms    8.3 ms
// i.e. 3.2 to 4.2 GB/s of images read and written: memory-bound.
#include <benchmark/benchmark.h>

#include <opencv2/core.hpp>

#include "runtime/textures.h"

namespace fourd {
namespace {

void BM_TextureBlend(benchmark::State& state) {
  const int size = static_cast<int>(state.range(0));
  const int count = static_cast<int>(state.range(1));
  AssetTextures textures;
  textures.width = textures.height = size;
  cv::RNG rng(7);
  for (int k = 0; k < count; ++k) {
    cv::Mat image(size, size, CV_8UC3);
    rng.fill(image, cv::RNG::UNIFORM, 0, 256);
    textures.images.push_back(image);
  }
  TextureBlend blend;
  blend.count = count;
  for (int k = 0; k < count; ++k) {
    blend.images[k] = k;
    blend.weights[k] = 1.0f / count;
  }
  cv::Mat out;
  blend_texture_image(textures, blend, &out);
  for (auto _ : state) {
    blend_texture_image(textures, blend, &out);
    benchmark::DoNotOptimize(out.data);
    benchmark::ClobberMemory();
  }
  const double bytes = static_cast<double>(textures.image_bytes()) * (count + 1);
  state.SetBytesProcessed(static_cast<std::int64_t>(bytes * state.iterations()));
  state.counters["Mtexels/s"] = benchmark::Counter(static_cast<double>(size) * size * 1e-6,
                                                   benchmark::Counter::kIsIterationInvariantRate);
}
BENCHMARK(BM_TextureBlend)
    ->ArgsProduct({{256, 512, 1024}, {2, 4, 8}})
    ->Unit(benchmark::kMicrosecond);

}  // namespace
}  // namespace fourd
