#pragma once
// Isosurface extraction from a scalar field sampled on a regular grid, by marching
// tetrahedra over the Freudenthal (6-tetrahedra) split of every cell. Unlike marching cubes it
// needs no case table and has no ambiguous cases: the surface is closed and manifold wherever
// it does not touch the grid border (the border is treated as outside).
#include <Eigen/Core>
#include <Eigen/Geometry>
#include <functional>
#include <vector>

#include "pipeline/core/mesh.h"

namespace fourd {

// values[(z * ny + y) * nx + x] at world point origin + voxel * (x, y, z).
struct ScalarGrid {
  Eigen::Vector3d origin = Eigen::Vector3d::Zero();
  double voxel = 1;
  int nx = 0, ny = 0, nz = 0;
  std::vector<float> values;

  std::size_t index(int x, int y, int z) const {
    return (static_cast<std::size_t>(z) * ny + y) * nx + x;
  }
  float at(int x, int y, int z) const { return values[index(x, y, z)]; }
  Eigen::Vector3d point(int x, int y, int z) const {
    return origin + voxel * Eigen::Vector3d(x, y, z);
  }
};

// The surface {value == iso}, inside = values below iso; triangles face outward (towards
// larger values). Samples that are NaN, and the space beyond the grid, count as outside by one
// voxel (as a signed distance field would).
Mesh extract_isosurface(const ScalarGrid& grid, float iso = 0.0f);

// Every `step`-th sample of the grid in each direction (the same field on a coarser grid).
ScalarGrid subsample(const ScalarGrid& grid, int step);

// Moves the vertices of `mesh` onto the level set {value == iso} of the grid's trilinear
// interpolation, by Newton steps along its gradient (each at most one voxel). A vertex stays
// where it is when its neighbourhood holds a NaN sample or lies beyond the grid, when the
// gradient vanishes (the field is flat there, e.g. truncated), when it would move farther than
// `max_move` [m], or when it does not reach the level set within a tenth of a voxel. Vertices
// of a triangle the moves would fold over (its normal turned by more than 90 degrees) stay
// too. Returns the number of vertices moved.
int project_to_isosurface(Mesh& mesh, const ScalarGrid& grid, float iso, double max_move);

}  // namespace fourd
