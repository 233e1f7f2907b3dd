#include "stages/align/shape_descriptor.h"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <limits>

namespace fourd::align {

SolidGrid voxelize_solid(const Mesh& mesh, double voxel, int padding) {
  SolidGrid grid;
  grid.voxel = voxel;
  if (mesh.empty()) return grid;
  Vec3f lo, hi;
  bounding_box(mesh, &lo, &hi);
  grid.origin = lo.cast<double>() - Eigen::Vector3d::Constant(padding * voxel);
  const Eigen::Vector3d extent = (hi - lo).cast<double>();
  grid.nx = static_cast<int>(std::ceil(extent.x() / voxel)) + 2 * padding;
  grid.ny = static_cast<int>(std::ceil(extent.y() / voxel)) + 2 * padding;
  grid.nz = static_cast<int>(std::ceil(extent.z() / voxel)) + 2 * padding;
  grid.inside.assign(static_cast<std::size_t>(grid.nx) * grid.ny * grid.nz, 0);

  // Column centres are nudged by an irrational fraction of a voxel so that no column passes
  // exactly through a mesh vertex or edge (which would count a crossing twice or never).
  const double nudge_x = voxel * 1e-4 * std::sqrt(2.0), nudge_y = voxel * 1e-4 * std::sqrt(3.0);
  auto column_x = [&](int i) { return grid.origin.x() + voxel * (i + 0.5) + nudge_x; };
  auto column_y = [&](int j) { return grid.origin.y() + voxel * (j + 0.5) + nudge_y; };

  std::vector<std::vector<float>> crossings(static_cast<std::size_t>(grid.nx) * grid.ny);
  for (const Tri& t : mesh.triangles) {
    const Eigen::Vector3d a = mesh.positions[t[0]].cast<double>();
    const Eigen::Vector3d b = mesh.positions[t[1]].cast<double>();
    const Eigen::Vector3d c = mesh.positions[t[2]].cast<double>();
    const double area = (b.x() - a.x()) * (c.y() - a.y()) - (b.y() - a.y()) * (c.x() - a.x());
    if (area == 0) continue;  // vertical in projection: no column crosses it
    const double min_x = std::min({a.x(), b.x(), c.x()}), max_x = std::max({a.x(), b.x(), c.x()});
    const double min_y = std::min({a.y(), b.y(), c.y()}), max_y = std::max({a.y(), b.y(), c.y()});
    const int i0 = std::max(0, static_cast<int>(std::floor((min_x - grid.origin.x()) / voxel - 0.5)));
    const int i1 = std::min(grid.nx - 1, static_cast<int>(std::ceil((max_x - grid.origin.x()) / voxel)));
    const int j0 = std::max(0, static_cast<int>(std::floor((min_y - grid.origin.y()) / voxel - 0.5)));
    const int j1 = std::min(grid.ny - 1, static_cast<int>(std::ceil((max_y - grid.origin.y()) / voxel)));
    for (int j = j0; j <= j1; ++j) {
      const double y = column_y(j);
      for (int i = i0; i <= i1; ++i) {
        const double x = column_x(i);
        // Edge functions = signed sub-areas opposite each corner.
        const double wa = (b.x() - x) * (c.y() - y) - (b.y() - y) * (c.x() - x);
        const double wb = (c.x() - x) * (a.y() - y) - (c.y() - y) * (a.x() - x);
        const double wc = (a.x() - x) * (b.y() - y) - (a.y() - y) * (b.x() - x);
        const bool inside = area > 0 ? (wa > 0 && wb > 0 && wc > 0) : (wa < 0 && wb < 0 && wc < 0);
        if (!inside) continue;
        const double z = (wa * a.z() + wb * b.z() + wc * c.z()) / area;
        crossings[static_cast<std::size_t>(j) * grid.nx + i].push_back(static_cast<float>(z));
      }
    }
  }
  for (int j = 0; j < grid.ny; ++j) {
    for (int i = 0; i < grid.nx; ++i) {
      auto& zs = crossings[static_cast<std::size_t>(j) * grid.nx + i];
      if (zs.size() < 2) continue;
      std::sort(zs.begin(), zs.end());
      for (std::size_t k = 0; k + 1 < zs.size(); k += 2) {
        const int k0 = std::max(0, static_cast<int>(std::ceil((zs[k] - grid.origin.z()) / voxel - 0.5)));
        const int k1 = std::min(grid.nz - 1,
                                static_cast<int>(std::floor((zs[k + 1] - grid.origin.z()) / voxel - 0.5)));
        for (int z = k0; z <= k1; ++z) grid.inside[grid.index(i, j, z)] = 1;
      }
    }
  }
  return grid;
}

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
