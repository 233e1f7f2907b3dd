#include "pipeline/geometry/shell.h"

#include <fmt/format.h>

#include <Eigen/Geometry>
#include <algorithm>

#include "pipeline/core/error.h"

namespace fourd {
namespace {

void require_grid(const TubeGrid& grid) {
  if (grid.rings < 2 || grid.columns < 3) {
    throw InputError(fmt::format("tube shell: needs at least 2 rings of 3 columns, not {} of {}",
                                 grid.rings, grid.columns));
  }
}

}  // namespace

std::vector<Tri> tube_shell_triangles(const TubeGrid& grid) {
  require_grid(grid);
  const int n = grid.size();
  auto outer = [&](int r, int c) { return grid.index(r, (c + grid.columns) % grid.columns); };
  auto inner = [&](int r, int c) { return n + outer(r, c); };
  std::vector<Tri> triangles;
  triangles.reserve(static_cast<std::size_t>(4 * grid.columns * grid.rings));
  for (int r = 0; r + 1 < grid.rings; ++r) {
    for (int c = 0; c < grid.columns; ++c) {
      // a, b along ring r, d, e below them on ring r + 1: seen from outside a is top left.
      const int a = outer(r, c), b = outer(r, c + 1), d = outer(r + 1, c), e = outer(r + 1, c + 1);
      triangles.emplace_back(a, d, e);
      triangles.emplace_back(a, e, b);
      const int ai = inner(r, c), bi = inner(r, c + 1), di = inner(r + 1, c), ei = inner(r + 1, c + 1);
      triangles.emplace_back(ai, ei, di);
      triangles.emplace_back(ai, bi, ei);
    }
  }
  // The rims: ring 0 faces away from the tube, the last ring along it.
  const int last = grid.rings - 1;
  for (int c = 0; c < grid.columns; ++c) {
    const int o0 = outer(0, c), o1 = outer(0, c + 1), i0 = inner(0, c), i1 = inner(0, c + 1);
    triangles.emplace_back(o0, o1, i1);
    triangles.emplace_back(o0, i1, i0);
    const int p0 = outer(last, c), p1 = outer(last, c + 1), j0 = inner(last, c), j1 = inner(last, c + 1);
    triangles.emplace_back(p0, j1, p1);
    triangles.emplace_back(p0, j0, j1);
  }
  return triangles;
}

std::vector<Vec3f> tube_shell_positions(const TubeGrid& grid, const std::vector<Eigen::Vector3d>& sheet,
                                        double thickness) {
  require_grid(grid);
  if (static_cast<int>(sheet.size()) != grid.size()) {
    throw InputError(fmt::format("tube shell: {} sheet points for a grid of {} x {}", sheet.size(),
                                 grid.rings, grid.columns));
  }
  const int n = grid.size();
  auto at = [&](int r, int c) -> const Eigen::Vector3d& {
    return sheet[static_cast<std::size_t>(grid.index(r, (c + grid.columns) % grid.columns))];
  };
  std::vector<Vec3f> out(static_cast<std::size_t>(2 * n));
  for (int r = 0; r < grid.rings; ++r) {
    Eigen::Vector3d centroid = Eigen::Vector3d::Zero();
    for (int c = 0; c < grid.columns; ++c) centroid += at(r, c);
    centroid /= grid.columns;
    for (int c = 0; c < grid.columns; ++c) {
      const Eigen::Vector3d along = at(std::min(r + 1, grid.rings - 1), c) - at(std::max(r - 1, 0), c);
      const Eigen::Vector3d around = at(r, c + 1) - at(r, c - 1);
      Eigen::Vector3d normal = along.cross(around);
      if (normal.norm() < 1e-12) {
        const Eigen::Vector3d axis = along.norm() > 1e-12 ? along.normalized() : Eigen::Vector3d::Zero();
        normal = at(r, c) - centroid;
        normal -= normal.dot(axis) * axis;
      }
      if (normal.norm() > 1e-12) normal.normalize();
      const Eigen::Vector3d offset = 0.5 * thickness * normal;
      out[static_cast<std::size_t>(grid.index(r, c))] = (at(r, c) + offset).cast<float>();
      out[static_cast<std::size_t>(n + grid.index(r, c))] = (at(r, c) - offset).cast<float>();
    }
  }
  return out;
}

}  // namespace fourd
