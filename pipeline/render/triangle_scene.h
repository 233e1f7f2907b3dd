#pragma once
// A triangle mesh in an Embree scene, for the two questions the texture stage and the renderers
// ask: is the segment from a surface point to a camera (or a light) blocked, and what does a
// camera ray hit first.
#include <Eigen/Core>
#include <memory>
#include <vector>

#include "pipeline/core/mesh.h"

namespace fourd {

struct SceneHit {
  int face = -1;                                     // -1: the ray misses
  Eigen::Vector3f bary = Eigen::Vector3f::Zero();    // barycentric coordinates in the face
  float distance = 0;                                // along the ray [m]
};

class TriangleScene {
 public:
  // Builds the BVH of `positions` (#V) and `triangles` (#F).
  TriangleScene(const std::vector<Vec3f>& positions, const std::vector<Tri>& triangles);
  ~TriangleScene();
  TriangleScene(const TriangleScene&) = delete;
  TriangleScene& operator=(const TriangleScene&) = delete;

  // Whether anything lies on the ray (origin, direction) between tnear and tfar. Thread-safe.
  bool occluded(const Eigen::Vector3f& origin, const Eigen::Vector3f& direction, float tnear,
                float tfar) const;
  // First hit along the ray (direction need not be unit; distance is then in its units).
  SceneHit intersect(const Eigen::Vector3f& origin, const Eigen::Vector3f& direction) const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace fourd
