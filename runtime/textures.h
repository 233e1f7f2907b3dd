#pragma once
// The captured appearance at run time. The texture stage bakes one texture per captured frame,
// all in one UV atlas of the template; the asset keeps, per motion space, K key textures of each
// input take at evenly spaced phases of the space's normalised time t, and the runtime blends
// them with the geometry's input weights w (the weights Eq. 1 is evaluated at) and linearly
// between the two key phases around t, so appearance follows the blend.
//
// Key phases of a space with K keys: one-shot, t_k = k / (K - 1) for k = 0 .. K-1 (K >= 2);
// cyclic, t_k = k / K (t = 1 closes the cycle onto t = 0, so the last key blends into the
// first). Image index of input i, key k of space s: spaces[s].first + i * K + k.
//
// The atlas keeps the geometry's vertex arrays intact: UVs are per triangle corner
// (corner_uvs[3 f + c] for corner c of face f), so a renderer draws the blended positions of
// runtime/blend.h with these UVs (a GPU renderer duplicates vertices at chart seams itself).
//
// Blending is cheap and allocation-free: texture_blend_add() lists at most kMaxTextureSources
// images and weights (a cross-fade adds the fading space's too); a shader blends them, and
// blend_texture_image() does it on the CPU for renderers without shaders.
//
// The web build (web/, WebAssembly, no OpenCV) defines FOURD_ENCODED_TEXTURES: there the images
// stay the JPEG files the asset stores (their sizes checked against the announced one), the
// browser decodes them, and blend_texture_image() does not exist.
#include <array>
#include <cstdint>
#include <span>
#include <vector>
#ifndef FOURD_ENCODED_TEXTURES
#include <opencv2/core.hpp>
#endif

#include "pipeline/core/mesh.h"

namespace fourd {

struct SpaceTextures {
  int keys = 0;   // K key phases per input (>= 2; 0 for a space without textures)
  int first = 0;  // index of the space's first image in AssetTextures::images
};

struct AssetTextures {
  int width = 0, height = 0;      // texels of every image
  std::vector<Vec2f> corner_uvs;  // #F x 3: UV of each triangle corner (OBJ convention, v up)
  std::vector<SpaceTextures> spaces;  // one per motion space of the graph
#ifndef FOURD_ENCODED_TEXTURES
  std::vector<cv::Mat> images;    // CV_8UC3 BGR, width x height, continuous
#else
  std::vector<std::vector<std::uint8_t>> images;  // the asset's JPEG files, width x height
#endif
  int jpeg_quality = 90;          // how the asset file stores them (JPEG, 1..100)

  bool empty() const { return images.empty(); }
  std::size_t image_bytes() const { return static_cast<std::size_t>(width) * height * 3; }
  // Sizes and counts against the graph's spaces: `inputs[s]` the input count of space s,
  // `triangles` the template's. Throws InputError naming what disagrees.
  void check(std::span<const int> inputs, std::size_t triangles) const;
};

// The images a frame blends and their weights (summing to 1 when complete).
inline constexpr int kMaxTextureSources = 12;  // 2 spaces (cross-fade) x 3 inputs x 2 keys
struct TextureBlend {
  int count = 0;
  std::array<int, kMaxTextureSources> images{};
  std::array<float, kMaxTextureSources> weights{};
};

// Adds space `space`'s key textures at normalised time t (clamped to [0, 1]) and input weights
// w (N values, projected onto the simplex like the geometry's: negatives count as zero, the rest
// divided by its sum, all zero means equal), every weight multiplied by `scale`. Entries with a
// zero weight are left out. No allocation.
void texture_blend_add(const AssetTextures& textures, int space, bool cyclic, double t,
                       std::span<const float> w, float scale, TextureBlend* out);

#ifndef FOURD_ENCODED_TEXTURES
// out = sum_k weights[k] * images[k], rounded to 8 bits. `out` is (re)allocated only when it is
// not already width x height CV_8UC3, so a caller that keeps it allocates once.
void blend_texture_image(const AssetTextures& textures, const TextureBlend& blend, cv::Mat* out);
#endif

}  // namespace fourd
