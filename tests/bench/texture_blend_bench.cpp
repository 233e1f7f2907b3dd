// The CPU texture blend of the textured runtime (blend_texture_image, runtime/textures.h):
// the frame's key textures (8-bit BGR) mixed with their weights into a kept image, for
// renderers without shaders. Arguments: texture side (256, 512, 1024) and number of images
// blended: 2 (one take between two key phases), 4 (two takes), 8 (a cross-fade of two such
// blends).
//
//   fourd_bench --benchmark_filter=BM_TextureBlend
//
// Results are in the README's runtime section.
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
