#pragma once
// Unlit rendering of a textured mesh into a calibrated camera (Embree ray per pixel centre,
// lens distortion included, bilinear texture lookup): how validation and the tests compare a
// baked texture with what the cameras recorded.
#include <memory>
#include <opencv2/core.hpp>

#include "pipeline/core/camera.h"
#include "pipeline/core/mesh.h"

namespace fourd::texture {

struct TexturedView {
  cv::Mat image;  // CV_32FC3 BGR in [0, 1]; 0 off the mesh
  cv::Mat mask;   // CV_8UC1: 255 where the mesh covers the pixel centre
};

class TexturedRenderer {
 public:
  // `mesh` needs per-vertex or per-corner UVs (OBJ convention, v up) addressing `texture`
  // (CV_8UC3 or CV_32FC3, BGR). Throws InputError when it has none.
  TexturedRenderer(const Mesh& mesh, const cv::Mat& texture);
  ~TexturedRenderer();
  TexturedRenderer(const TexturedRenderer&) = delete;
  TexturedRenderer& operator=(const TexturedRenderer&) = delete;

  TexturedView render(const Camera& camera) const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

// Squared error between a render and an image (8-bit BGR) over the pixels of `mask`, in 8-bit
// levels summed over the three channels, and the number of values (3 per pixel).
struct ImageError {
  double sum_squared = 0;
  std::int64_t values = 0;
  void add(const ImageError& other) {
    sum_squared += other.sum_squared;
    values += other.values;
  }
  double psnr_db() const;  // 10 log10(255^2 / MSE); infinity for a perfect match
};
ImageError image_error(const cv::Mat& rendered, const cv::Mat& image, const cv::Mat& mask);

}  // namespace fourd::texture
