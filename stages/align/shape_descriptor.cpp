#include "stages/align/shape_descriptor.h"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <limits>

namespace fourd::align {

ShapeDescriptor compute_shape_descriptor(const Mesh& mesh, const DescriptorOptions& options) {
  ShapeDescriptor d;
  const int shells = options.shells, bands = options.elevations, sectors = options.sectors;
  d.bins.assign(static_cast<std::size_t>(shells) * bands * sectors, 0.0f);
  const SolidGrid grid = voxelize_solid(mesh, options.voxel);
  std::size_t count = 0;
  Eigen::Vector3d sum = Eigen::Vector3d::Zero();
  for (int z = 0; z < grid.nz; ++z) {
    for (int y = 0; y < grid.ny; ++y) {
      for (int x = 0; x < grid.nx; ++x) {
        if (!grid.inside[grid.index(x, y, z)]) continue;
        sum += grid.center(x, y, z);
        ++count;
      }
    }
  }
  if (count == 0) return d;
  d.centroid = sum / static_cast<double>(count);
  d.volume = static_cast<double>(count) * std::pow(options.voxel, 3);

  const int up = options.up_axis, h1 = (up + 1) % 3, h2 = (up + 2) % 3;
  const double weight = 1.0 / static_cast<double>(count);
  std::vector<double> bins(d.bins.size(), 0.0);
  for (int z = 0; z < grid.nz; ++z) {
    for (int y = 0; y < grid.ny; ++y) {
      for (int x = 0; x < grid.nx; ++x) {
        if (!grid.inside[grid.index(x, y, z)]) continue;
        const Eigen::Vector3d v = grid.center(x, y, z) - d.centroid;
        const double r = v.norm();
        const int shell = std::min(shells - 1, static_cast<int>(r / options.radius * shells));
        const double cos_elevation = r > 0 ? v[up] / r : 0.0;
        const int band = std::clamp(static_cast<int>((cos_elevation + 1) / 2 * bands), 0, bands - 1);
        const double azimuth = std::atan2(v[h2], v[h1]);  // (-pi, pi], grows with rotation about up
        const int sector =
            std::clamp(static_cast<int>((azimuth + M_PI) / (2 * M_PI) * sectors), 0, sectors - 1);
        bins[(static_cast<std::size_t>(shell) * bands + band) * sectors + sector] += weight;
      }
    }
  }
  for (std::size_t i = 0; i < bins.size(); ++i) d.bins[i] = static_cast<float>(bins[i]);
  return d;
}

ShapeDistance shape_distance(const ShapeDescriptor& a, const ShapeDescriptor& b,
                             const DescriptorOptions& options) {
  const int sectors = options.sectors;
  const std::size_t rows = a.bins.size() / sectors;
  ShapeDistance best{std::numeric_limits<double>::infinity(), 0};
  for (int s = 0; s < sectors; ++s) {
    double sum = 0;
    for (std::size_t r = 0; r < rows; ++r) {
      const float* ra = a.bins.data() + r * sectors;
      const float* rb = b.bins.data() + r * sectors;
      for (int k = 0; k < sectors; ++k) {
        // Sector k of b lands in sector k + s once b is rotated by s sectors.
        const double diff = ra[(k + s) % sectors] - rb[k];
        sum += diff * diff;
      }
    }
    if (sum < best.value) best = {sum, s > sectors / 2 ? s - sectors : s};
  }
  best.value = std::sqrt(best.value);
  return best;
}

DistanceMatrix pairwise_shape_distances(const std::vector<ShapeDescriptor>& descriptors,
                                        const DescriptorOptions& options) {
  const int n = static_cast<int>(descriptors.size());
  DistanceMatrix m;
  m.value = Eigen::MatrixXd::Zero(n, n);
  m.shift = Eigen::MatrixXi::Zero(n, n);
  tbb::parallel_for(0, n, [&](int i) {
    for (int j = i + 1; j < n; ++j) {
      ShapeDistance d = shape_distance(descriptors[i], descriptors[j], options);
      m.value(i, j) = m.value(j, i) = d.value;
      m.shift(i, j) = d.shift;
      m.shift(j, i) = -d.shift;
    }
  });
  return m;
}

}  // namespace fourd::align
