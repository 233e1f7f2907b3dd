#pragma once
// The texture of one frame from the studio's images: every atlas texel is a point on the posed
// surface; each camera that sees it (in front, not at a grazing angle, not occluded — an Embree
// ray from the point to the camera — and away from the mesh's outline in that image, where
// pixels mix in the backdrop) contributes its image colour there, weighted by the viewing
// angle and the camera's resolution at that point. Colours are blended, chart seams levelled
// (both sides of a cut meet at their mean, the correction fading into the charts), texels no
// camera sees filled from the surface around them (and marked), and the gutters filled by
// dilation so lookups at chart borders do not bleed.
#include <opencv2/core.hpp>
#include <vector>

#include "pipeline/core/camera.h"
#include "pipeline/core/config.h"
#include "pipeline/core/mesh.h"
#include "pipeline/render/textured_render.h"  // sample_bilinear
#include "stages/texture/atlas.h"

namespace fourd::texture {

// Tuned values, not options (docs/texture.md, "Advanced"); internal_lengths() lists the lengths
// scaled to the subject.
struct BakeOptions {
  double angle_power = 4;          // view weight ~ cos(viewing angle)^angle_power
  double min_cos = 0.2;            // views more grazing than acos(min_cos) are not used
  double edge_pixels = 3;          // weight ramps from 0 at the mesh's outline to 1 at this
                                   // distance inside it [px]
  double occlusion_offset = 0.002; // visibility rays start this far above the surface [m]
  int seam_width = 6;              // seam corrections fade over about this many texels; 0: off

  template <class V>
  void internal_lengths(V& v) {
    v("occlusion_offset", occlusion_offset, "", Length{0, 1});
  }
};

// One camera's image of the frame (8-bit BGR, the camera's calibrated size).
struct View {
  const Camera* camera = nullptr;
  cv::Mat image;
};

struct BakedTexture {
  cv::Mat color;                      // resolution^2, CV_32FC3, BGR in [0, 1]
  cv::Mat unseen;                     // CV_8UC1: 255 where no camera saw the texel (filled)
  int texels = 0;                     // texels on the surface
  int unseen_texels = 0;
  std::vector<int> texels_per_view;   // texels each view contributed to
  double seam_rms_before = 0;         // colour difference across chart seams [8-bit levels]
  double seam_rms_after = 0;          // ... after levelling
};

// Bakes one frame: `positions` (#V) posed in the template's topology `triangles`. Throws
// InputError when no camera sees any part of the surface.
BakedTexture bake_texture(const Atlas& atlas, const TexelMap& texels,
                          const std::vector<Vec3f>& positions, const std::vector<Tri>& triangles,
                          const std::vector<View>& views, const BakeOptions& options);

// The texture for writing: CV_8UC3, or CV_32FC3 unchanged when `float_output`.
cv::Mat texture_for_output(const cv::Mat& color, bool float_output);

}  // namespace fourd::texture
