#pragma once
// Small closed shapes for tests: an icosphere and a box, both centred on the origin with
// triangles counter-clockwise seen from outside, and the isosurface of any signed distance
// (a torus, a fine sphere). Header-only so any test can include it.
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <map>
#include <utility>

#include "pipeline/core/isosurface.h"
#include "pipeline/core/mesh.h"

namespace fourd::test {

// Icosahedron subdivided `subdivisions` times (each step splits every triangle in four),
// vertices on the sphere of `radius`. 10 * 4^s + 2 vertices, 20 * 4^s triangles.
inline Mesh make_icosphere(int subdivisions, float radius = 1.0f) {
  const float t = (1.0f + std::sqrt(5.0f)) / 2.0f;
  Mesh mesh;
  mesh.positions = {{-1, t, 0},  {1, t, 0},  {-1, -t, 0}, {1, -t, 0}, {0, -1, t},  {0, 1, t},
                    {0, -1, -t}, {0, 1, -t}, {t, 0, -1},  {t, 0, 1},  {-t, 0, -1}, {-t, 0, 1}};
  mesh.triangles = {{0, 11, 5}, {0, 5, 1},  {0, 1, 7},   {0, 7, 10}, {0, 10, 11},
                    {1, 5, 9},  {5, 11, 4}, {11, 10, 2}, {10, 7, 6}, {7, 1, 8},
                    {3, 9, 4},  {3, 4, 2},  {3, 2, 6},   {3, 6, 8},  {3, 8, 9},
                    {4, 9, 5},  {2, 4, 11}, {6, 2, 10},  {8, 6, 7},  {9, 8, 1}};
  for (int s = 0; s < subdivisions; ++s) {
    // One midpoint per edge, shared by the two triangles on either side.
    std::map<std::pair<int, int>, int> midpoints;
    auto midpoint = [&](int a, int b) {
      auto key = std::minmax(a, b);
      auto [it, inserted] = midpoints.try_emplace(key, static_cast<int>(mesh.positions.size()));
      if (inserted) {
        Vec3f m = 0.5f * (mesh.positions[a] + mesh.positions[b]);
        mesh.positions.push_back(m);
      }
      return it->second;
    };
    std::vector<Tri> finer;
    finer.reserve(mesh.triangles.size() * 4);
    for (const Tri& tri : mesh.triangles) {
      int ab = midpoint(tri[0], tri[1]);
      int bc = midpoint(tri[1], tri[2]);
      int ca = midpoint(tri[2], tri[0]);
      finer.emplace_back(tri[0], ab, ca);
      finer.emplace_back(tri[1], bc, ab);
      finer.emplace_back(tri[2], ca, bc);
      finer.emplace_back(ab, bc, ca);
    }
    mesh.triangles = std::move(finer);
  }
  for (Vec3f& p : mesh.positions) p = p.normalized() * radius;
  return mesh;
}

// Axis-aligned box with edge lengths `size`: 8 shared corners, 12 triangles.
inline Mesh make_box(const Vec3f& size) {
  Mesh mesh;
  const Vec3f h = 0.5f * size;
  for (int i = 0; i < 8; ++i) {
    // Corner i has x from bit 0, y from bit 1, z from bit 2.
    mesh.positions.emplace_back((i & 1) ? h.x() : -h.x(), (i & 2) ? h.y() : -h.y(),
                                (i & 4) ? h.z() : -h.z());
  }
  mesh.triangles = {{0, 2, 3}, {0, 3, 1},   // -z
                    {4, 5, 7}, {4, 7, 6},   // +z
                    {0, 1, 5}, {0, 5, 4},   // -y
                    {2, 6, 7}, {2, 7, 3},   // +y
                    {0, 4, 6}, {0, 6, 2},   // -x
                    {1, 3, 7}, {1, 7, 5}};  // +x
  return mesh;
}

inline Mesh make_box(float size = 1.0f) { return make_box(Vec3f::Constant(size)); }

// Isosurface of `sdf` (negative inside) on a grid of `voxel` over [lo, hi].
template <class Sdf>
Mesh isosurface_of(const Sdf& sdf, const Eigen::Vector3d& lo, const Eigen::Vector3d& hi, double voxel) {
  ScalarGrid grid;
  grid.origin = lo;
  grid.voxel = voxel;
  grid.nx = static_cast<int>(std::ceil((hi.x() - lo.x()) / voxel)) + 1;
  grid.ny = static_cast<int>(std::ceil((hi.y() - lo.y()) / voxel)) + 1;
  grid.nz = static_cast<int>(std::ceil((hi.z() - lo.z()) / voxel)) + 1;
  grid.values.resize(static_cast<std::size_t>(grid.nx) * grid.ny * grid.nz);
  tbb::parallel_for(0, grid.nz, [&](int z) {
    for (int y = 0; y < grid.ny; ++y) {
      for (int x = 0; x < grid.nx; ++x) {
        grid.values[grid.index(x, y, z)] = static_cast<float>(sdf(grid.point(x, y, z)));
      }
    }
  });
  return extract_isosurface(grid, 0.0f);
}

// A sphere of `radius` as the isosurface of its distance on an 8 mm grid (over 10k vertices
// for 0.3 m: a fine isosurface to bring down to a few thousand).
inline Mesh fine_sphere(double radius) {
  const double reach = radius + 0.04;
  return isosurface_of([&](const Eigen::Vector3d& p) { return p.norm() - radius; },
                       Eigen::Vector3d::Constant(-reach), Eigen::Vector3d::Constant(reach), 0.008);
}

// The largest distance of a vertex from the sphere of `radius` about the origin [m].
inline double max_radial_error(const Mesh& mesh, double radius) {
  double worst = 0;
  for (const Vec3f& p : mesh.positions) {
    worst = std::max(worst, std::abs(p.cast<double>().norm() - radius));
  }
  return worst;
}

}  // namespace fourd::test
