#pragma once
// First-hit depth and normal maps of a triangle mesh seen by pinhole cameras (Embree).
// Reconstruction uses them to know, for every pixel, where the visual hull starts along its
// ray and which way the hull faces there.
#include <memory>
#include <opencv2/core.hpp>

#include "pipeline/core/mesh.h"
#include "stages/reconstruct/pinhole.h"

namespace fourd::reconstruct {

struct SurfaceRender {
  cv::Rect roi;    // the image region holding every hit (empty when the mesh is not seen)
  cv::Mat depth;   // full image, CV_32F: depth along the optical axis [m], 0 where the ray misses
  cv::Mat normal;  // full image, CV_32FC3: unit outward normal in world coordinates (0 on misses)
};

class MeshRaycaster {
 public:
  explicit MeshRaycaster(const Mesh& mesh);
  ~MeshRaycaster();
  MeshRaycaster(const MeshRaycaster&) = delete;
  MeshRaycaster& operator=(const MeshRaycaster&) = delete;

  // Casts one ray through every pixel centre of the mesh's bounding rectangle in `camera`.
  // Thread-safe.
  SurfaceRender render(const PinholeCamera& camera) const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace fourd::reconstruct
