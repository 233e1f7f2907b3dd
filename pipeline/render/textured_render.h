#pragma once
// Rendering a triangle mesh into a calibrated camera: one Embree ray per pixel centre, lens
// distortion included. With a texture the mesh is drawn unlit with a bilinear texture lookup
// (how validation and the tests compare a baked texture with what the cameras recorded, and
// how the player draws the captured appearance); without one it is shaded, a grey surface lit
// by a directional light (the player's fallback for an asset without textures). The same
// renderer follows a moving mesh: set_positions() rebuilds the ray-casting structure for new
// positions of the same triangles, set_texture() swaps the image.
#include <Eigen/Core>
#include <memory>
#include <opencv2/core.hpp>

#include "pipeline/core/camera.h"
#include "pipeline/core/mesh.h"

namespace fourd {

struct RenderedView {
  cv::Mat image;  // CV_32FC3 BGR in [0, 1]; 0 off the mesh
  cv::Mat mask;   // CV_8UC1: 255 where the mesh covers the pixel centre
};

// Light of the shaded (untextured) mode: albedo * (ambient + (1 - ambient) max(0, n . l)), n the
// face normal turned towards the camera.
struct Shading {
  Eigen::Vector3f light = Eigen::Vector3f(0.4f, 0.3f, 0.87f).normalized();  // towards the light
  float ambient = 0.3f;
  Eigen::Vector3f albedo = Eigen::Vector3f(0.72f, 0.72f, 0.75f);  // BGR in [0, 1]
};

class MeshRenderer {
 public:
  // Textured: `mesh` needs per-vertex or per-corner UVs (OBJ convention, v up) addressing
  // `texture` (CV_8UC3 or CV_32FC3, BGR; not copied: keep it alive and unchanged while
  // rendering, or hand a new one to set_texture). Throws InputError when either is missing.
  MeshRenderer(const Mesh& mesh, const cv::Mat& texture);
  // Shaded: positions and triangles only.
  MeshRenderer(const Mesh& mesh, const Shading& shading);
  ~MeshRenderer();
  MeshRenderer(const MeshRenderer&) = delete;
  MeshRenderer& operator=(const MeshRenderer&) = delete;

  // New positions of the same vertices (#V); rebuilds the ray-casting structure. Throws
  // InputError for another vertex count.
  void set_positions(const std::vector<Vec3f>& positions);
  // A new texture for a textured renderer (same rules as the constructor's).
  void set_texture(const cv::Mat& texture);
  bool textured() const;

  RenderedView render(const Camera& camera) const;
  // Whether the mesh blocks the ray between tnear and tfar (e.g. a shadow on the ground).
  bool occluded(const Eigen::Vector3f& origin, const Eigen::Vector3f& direction, float tnear,
                float tfar) const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

// Bilinear lookup of a BGR image (8-bit or float) at pixel coordinates with centres at +0.5
// (the calibration's convention); clamped at the borders. Result in [0, 1].
Eigen::Vector3f sample_bilinear(const cv::Mat& image, double x, double y);

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

}  // namespace fourd
