#include "stages/synth/implicit_mesh.h"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>

namespace fourd::synth::detail {

using Eigen::Vector3d;

ScalarGrid sample_field(const std::function<double(const Vector3d&)>& field, const Vector3d& lo,
                        const Vector3d& hi, double spacing) {
  ScalarGrid grid;
  grid.origin = lo;
  grid.voxel = spacing;
  grid.nx = static_cast<int>(std::ceil((hi.x() - lo.x()) / spacing)) + 1;
  grid.ny = static_cast<int>(std::ceil((hi.y() - lo.y()) / spacing)) + 1;
  grid.nz = static_cast<int>(std::ceil((hi.z() - lo.z()) / spacing)) + 1;
  grid.values.resize(static_cast<std::size_t>(grid.nx) * static_cast<std::size_t>(grid.ny) *
                     static_cast<std::size_t>(grid.nz));
  tbb::parallel_for(0, grid.nz, [&](int k) {
    for (int j = 0; j < grid.ny; ++j) {
      for (int i = 0; i < grid.nx; ++i) grid.values[grid.index(i, j, k)] = static_cast<float>(field(grid.point(i, j, k)));
    }
  });
  return grid;
}

ScalarGrid sample_distance_field(const std::function<double(const Vector3d&)>& field, const Vector3d& lo,
                                 const Vector3d& hi, double spacing, double lipschitz) {
  constexpr int kStride = 4;
  ScalarGrid grid;
  grid.origin = lo;
  grid.voxel = spacing;
  grid.nx = static_cast<int>(std::ceil((hi.x() - lo.x()) / spacing)) + 1;
  grid.ny = static_cast<int>(std::ceil((hi.y() - lo.y()) / spacing)) + 1;
  grid.nz = static_cast<int>(std::ceil((hi.z() - lo.z()) / spacing)) + 1;
  // The coarse grid covers the fine one.
  const int cx = (grid.nx - 1) / kStride + 2, cy = (grid.ny - 1) / kStride + 2, cz = (grid.nz - 1) / kStride + 2;
  const Vector3d coarse_hi = lo + kStride * spacing * Vector3d(cx - 1, cy - 1, cz - 1);
  const ScalarGrid coarse = sample_field(field, lo, coarse_hi, kStride * spacing);
  // A fine edge that crosses the surface has its ends within one spacing of it, so a coarse
  // cell whose corners are all further than its diagonal plus one spacing holds no end of such
  // an edge: its inside needs signs only.
  const double safe = (std::sqrt(3.0) * kStride + 1) * spacing * lipschitz;
  grid.values.resize(static_cast<std::size_t>(grid.nx) * static_cast<std::size_t>(grid.ny) *
                     static_cast<std::size_t>(grid.nz));
  tbb::parallel_for(0, grid.nz, [&](int k) {
    const int ck = std::min(k / kStride, coarse.nz - 2);
    for (int j = 0; j < grid.ny; ++j) {
      const int cj = std::min(j / kStride, coarse.ny - 2);
      for (int i = 0; i < grid.nx; ++i) {
        const int ci = std::min(i / kStride, coarse.nx - 2);
        double corner[8];
        bool far = true;
        for (int c = 0; c < 8; ++c) {
          corner[c] = coarse.values[coarse.index(ci + (c & 1), cj + (c >> 1 & 1), ck + (c >> 2 & 1))];
          far = far && std::abs(corner[c]) > safe && (corner[c] > 0) == (corner[0] > 0);
        }
        float& out = grid.values[grid.index(i, j, k)];
        if (!far) {
          out = static_cast<float>(field(grid.point(i, j, k)));
          continue;
        }
        const double tx = static_cast<double>(i - ci * kStride) / kStride, ty = static_cast<double>(j - cj * kStride) / kStride,
                     tz = static_cast<double>(k - ck * kStride) / kStride;
        double v = 0;
        for (int c = 0; c < 8; ++c) {
          v += corner[c] * ((c & 1) ? tx : 1 - tx) * ((c >> 1 & 1) ? ty : 1 - ty) * ((c >> 2 & 1) ? tz : 1 - tz);
        }
        out = static_cast<float>(v);
      }
    }
  });
  return grid;
}

}  // namespace fourd::synth::detail
