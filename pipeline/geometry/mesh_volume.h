#pragma once
// The volume a closed mesh encloses.
#include <Eigen/Core>

#include "pipeline/core/mesh.h"

namespace fourd {

// Volume enclosed by a closed, outward-oriented mesh [m^3] (divergence theorem); negative when
// its triangles face inward.
inline double enclosed_volume(const Mesh& mesh) {
  double six_volume = 0;
  for (const Tri& t : mesh.triangles) {
    const Eigen::Vector3d a = mesh.positions[t[0]].cast<double>(),
                          b = mesh.positions[t[1]].cast<double>(),
                          c = mesh.positions[t[2]].cast<double>();
    six_volume += a.dot(b.cross(c));
  }
  return six_volume / 6;
}

}  // namespace fourd
