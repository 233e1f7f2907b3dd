#include "runtime/textures.h"

#include <fmt/format.h>

#include <algorithm>
#include <cassert>
#include <cmath>

#include "pipeline/core/error.h"

namespace fourd {

void AssetTextures::check(std::span<const int> inputs, std::size_t triangles) const {
  if (empty()) return;
  if (width < 1 || height < 1 || width > 16384 || height > 16384) {
    throw InputError(fmt::format("textures: bad image size {} x {}", width, height));
  }
  if (corner_uvs.size() != 3 * triangles) {
    throw InputError(fmt::format("textures: {} corner UVs for {} triangles (expected {})",
                                 corner_uvs.size(), triangles, 3 * triangles));
  }
  for (std::size_t k = 0; k < corner_uvs.size(); ++k) {
    if (!corner_uvs[k].allFinite()) {
      throw InputError(fmt::format("textures: corner UV {} is not finite", k));
    }
  }
  if (spaces.size() != inputs.size()) {
    throw InputError(fmt::format("textures: {} spaces of key textures for {} motion spaces",
                                 spaces.size(), inputs.size()));
  }
  std::size_t expected = 0;
  for (std::size_t s = 0; s < spaces.size(); ++s) {
    const SpaceTextures& t = spaces[s];
    if (t.keys != 0 && (t.keys < 2 || t.keys > 4096)) {
      throw InputError(fmt::format("textures: space {} has {} key phases (2 to 4096)", s, t.keys));
    }
    if (t.first != static_cast<int>(expected)) {
      throw InputError(fmt::format("textures: space {} starts at image {}, expected {}", s,
                                   t.first, expected));
    }
    expected += static_cast<std::size_t>(t.keys) * inputs[s];
  }
  if (images.size() != expected) {
    throw InputError(
        fmt::format("textures: {} key images, the spaces need {}", images.size(), expected));
  }
#ifndef FOURD_ENCODED_TEXTURES
  for (std::size_t k = 0; k < images.size(); ++k) {
    const cv::Mat& m = images[k];
    if (m.type() != CV_8UC3 || m.cols != width || m.rows != height || !m.isContinuous()) {
      throw InputError(fmt::format("textures: key image {} is {} x {} (type {}), expected {} x {} "
                                   "8-bit BGR",
                                   k, m.cols, m.rows, m.type(), width, height));
    }
  }
#endif
}

void texture_blend_add(const AssetTextures& textures, int space, bool cyclic, double t,
                       std::span<const float> w, float scale, TextureBlend* out) {
  if (textures.empty() || space < 0 || space >= static_cast<int>(textures.spaces.size())) return;
  const SpaceTextures& st = textures.spaces[space];
  const int keys = st.keys;
  if (keys < 2 || scale <= 0) return;
  const int n = static_cast<int>(w.size());
  assert(n >= 1 && n <= 3);
  std::array<float, 3> p{};
  float sum = 0;
  for (int i = 0; i < n; ++i) sum += (p[i] = std::max(0.f, w[i]));
  for (int i = 0; i < n; ++i) p[i] = sum > 0 ? p[i] / sum : 1.f / static_cast<float>(n);
  // The two key phases around t and the weight of the second.
  t = std::clamp(t, 0.0, 1.0);
  int k0 = 0, k1 = 0;
  double a = 0;
  if (cyclic) {
    const double u = t * keys;
    k0 = std::min(static_cast<int>(u), keys - 1);
    a = std::clamp(u - k0, 0.0, 1.0);
    k1 = (k0 + 1) % keys;
  } else {
    const double u = t * (keys - 1);
    k0 = std::min(static_cast<int>(u), keys - 2);
    a = std::clamp(u - k0, 0.0, 1.0);
    k1 = k0 + 1;
  }
  for (int i = 0; i < n; ++i) {
    const int base = st.first + i * keys;
    const float wk[2] = {static_cast<float>(scale * p[i] * (1 - a)),
                         static_cast<float>(scale * p[i] * a)};
    const int image[2] = {base + k0, base + k1};
    for (int j = 0; j < 2; ++j) {
      if (wk[j] <= 0 || out->count >= kMaxTextureSources) continue;
      out->images[out->count] = image[j];
      out->weights[out->count] = wk[j];
      ++out->count;
    }
  }
}

#ifndef FOURD_ENCODED_TEXTURES
void blend_texture_image(const AssetTextures& textures, const TextureBlend& blend, cv::Mat* out) {
  out->create(textures.height, textures.width, CV_8UC3);
  const std::size_t n = textures.image_bytes();
  std::uint8_t* dst = out->ptr<std::uint8_t>();
  if (blend.count == 0) {
    std::fill(dst, dst + n, std::uint8_t{0});
    return;
  }
  // Blocks small enough for a float accumulator on the stack: no allocation.
  constexpr std::size_t kBlock = 4096;
  float acc[kBlock];
  for (std::size_t start = 0; start < n; start += kBlock) {
    const std::size_t len = std::min(kBlock, n - start);
    {
      const std::uint8_t* src = textures.images[blend.images[0]].ptr<std::uint8_t>() + start;
      const float wt = blend.weights[0];
      for (std::size_t i = 0; i < len; ++i) acc[i] = wt * src[i];
    }
    for (int k = 1; k < blend.count; ++k) {
      const std::uint8_t* src = textures.images[blend.images[k]].ptr<std::uint8_t>() + start;
      const float wt = blend.weights[k];
      for (std::size_t i = 0; i < len; ++i) acc[i] += wt * src[i];
    }
    for (std::size_t i = 0; i < len; ++i) {
      dst[start + i] = static_cast<std::uint8_t>(std::clamp(acc[i] + 0.5f, 0.f, 255.f));
    }
  }
}

#endif

}  // namespace fourd
