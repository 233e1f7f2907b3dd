#include "pipeline/geometry/solid.h"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <random>

#include "pipeline/core/error.h"
#include "pipeline/core/isosurface.h"
#include "pipeline/geometry/components.h"
#include "pipeline/geometry/measures.h"
#include "pipeline/geometry/mesh_query.h"
#include "pipeline/geometry/surface_query.h"

namespace fourd {

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

Mesh surface_of_solid(const Mesh& mesh, const SolidGrid& solid) {
  const SurfaceQuery query(mesh);
  ScalarGrid grid;
  grid.origin = solid.origin + Eigen::Vector3d::Constant(0.5 * solid.voxel);  // voxel centres
  grid.voxel = solid.voxel;
  grid.nx = solid.nx;
  grid.ny = solid.ny;
  grid.nz = solid.nz;
  grid.values.resize(solid.inside.size());
  const float band = static_cast<float>(2 * solid.voxel);
  tbb::parallel_for(0, grid.nz, [&](int z) {
    for (int y = 0; y < grid.ny; ++y) {
      for (int x = 0; x < grid.nx; ++x) {
        const SurfaceHit hit = query.closest(grid.point(x, y, z).cast<float>(), band);
        const float d = hit.found ? hit.distance : band;
        grid.values[grid.index(x, y, z)] = solid.inside[solid.index(x, y, z)] ? -d : d;
      }
    }
  });
  return extract_isosurface(grid, 0.0f);
}

namespace {

// One step of binary dilation (grow) or erosion over the 6-neighbourhood; border voxels
// keep their value.
std::vector<std::uint8_t> morphology_step(const SolidGrid& g, const std::vector<std::uint8_t>& in,
                                          bool grow) {
  std::vector<std::uint8_t> out = in;
  tbb::parallel_for(1, g.nz - 1, [&](int z) {
    for (int y = 1; y < g.ny - 1; ++y) {
      for (int x = 1; x < g.nx - 1; ++x) {
        const std::uint8_t a = in[g.index(x - 1, y, z)], b = in[g.index(x + 1, y, z)],
                           c = in[g.index(x, y - 1, z)], d = in[g.index(x, y + 1, z)],
                           e = in[g.index(x, y, z - 1)], f = in[g.index(x, y, z + 1)];
        const std::uint8_t v = in[g.index(x, y, z)];
        out[g.index(x, y, z)] = grow ? (v | a | b | c | d | e | f) : (v & a & b & c & d & e & f);
      }
    }
  });
  return out;
}

std::vector<std::uint8_t> morphology(const SolidGrid& g, std::vector<std::uint8_t> v, bool grow,
                                     int steps) {
  for (int i = 0; i < steps; ++i) v = morphology_step(g, v, grow);
  return v;
}

}  // namespace

Mesh remove_small_handles(const Mesh& mesh, double voxel, int max_radius, double min_volume) {
  const int input_handles = check_manifold(mesh).handles;
  if (input_handles == 0) return mesh;
  const double input_volume = enclosed_volume(mesh);
  // Padding beyond the largest radius keeps the grown solid off the grid's border.
  SolidGrid solid = voxelize_solid(mesh, voxel, max_radius + 2);
  const std::vector<std::uint8_t> inside = solid.inside;
  Mesh best = mesh;
  int best_handles = input_handles < 0 ? std::numeric_limits<int>::max() : input_handles;
  // Keeps the surface of `solid` when it has fewer handles than the best so far; true when it
  // has none.
  auto consider = [&](const SolidGrid& edited) {
    const Mesh surface = surface_of_solid(mesh, edited);
    Mesh part = largest_component(surface);
    // The edit must not cut off or erase a limb: no piece of note apart from the body, and the
    // body's volume kept.
    const double volume = enclosed_volume(part);
    if (volume < 0.995 * enclosed_volume(surface) || volume < min_volume * input_volume) return false;
    const int handles = check_manifold(part).handles;
    if (handles < 0 || handles >= best_handles) return false;
    best = std::move(part);
    best_handles = handles;
    return handles == 0;
  };
  for (int r = 1; r <= max_radius; ++r) {
    const std::vector<std::uint8_t> closed =
        morphology(solid, morphology(solid, inside, true, r), false, r);
    // Closed then opened: tunnels filled and thin bridges (an arm merged with the body) cut.
    solid.inside = morphology(solid, morphology(solid, closed, false, r), true, r);
    if (consider(solid)) break;
    // Closed only: a sheet as thin as the opening (a garment) is erased by it, and its
    // perforations (holes of a re-meshing or a reconstruction through the thin cloth) are
    // handles that the closing alone fills.
    solid.inside = closed;
    if (consider(solid)) break;
  }
  return best;
}

Mesh remesh_fresh(const Mesh& mesh, double voxel, const Eigen::Vector3d& offset,
                  double noise_sigma, unsigned seed) {
  if (mesh.triangles.empty()) throw InputError("remesh_fresh: the mesh has no triangles");
  const MeshQuery query(mesh);
  Vec3f lo, hi;
  bounding_box(mesh, &lo, &hi);
  ScalarGrid grid;
  grid.voxel = voxel;
  grid.origin = lo.cast<double>() - Eigen::Vector3d::Constant(2 * voxel) + offset;
  const Eigen::Vector3d extent = hi.cast<double>() + Eigen::Vector3d::Constant(2 * voxel) - grid.origin;
  grid.nx = static_cast<int>(std::ceil(extent.x() / voxel)) + 1;
  grid.ny = static_cast<int>(std::ceil(extent.y() / voxel)) + 1;
  grid.nz = static_cast<int>(std::ceil(extent.z() / voxel)) + 1;
  const float band = static_cast<float>(2 * voxel);
  grid.values.assign(static_cast<std::size_t>(grid.nx) * grid.ny * grid.nz, band);

  // Inside by the winding number of the surface crossings along x, row by row: a garment's
  // shell that overlaps the body is inside their union, not outside it as by parity.
  tbb::parallel_for(0, grid.nz, [&](int z) {
    for (int y = 0; y < grid.ny; ++y) {
      const Eigen::Vector3d row = grid.point(0, y, z);
      const std::vector<MeshQuery::Crossing> xs = query.crossings_along_x(row.y(), row.z());
      std::size_t next = 0;
      int winding = 0;
      for (int x = 0; x < grid.nx; ++x) {
        const double px = row.x() + voxel * x;
        while (next < xs.size() && xs[next].x < px) winding += xs[next++].direction;
        if (winding != 0) grid.values[grid.index(x, y, z)] = -band;
      }
    }
  });
  // Exact distances where the sign changes within a cell (the only samples the isosurface uses).
  std::vector<float> signed_distance = grid.values;
  tbb::parallel_for(0, grid.nz, [&](int z) {
    for (int y = 0; y < grid.ny; ++y) {
      for (int x = 0; x < grid.nx; ++x) {
        const bool in = grid.at(x, y, z) < 0;
        bool boundary = false;
        for (int dz = -1; dz <= 1 && !boundary; ++dz) {
          for (int dy = -1; dy <= 1 && !boundary; ++dy) {
            for (int dx = -1; dx <= 1 && !boundary; ++dx) {
              const int a = x + dx, b = y + dy, c = z + dz;
              if (a < 0 || b < 0 || c < 0 || a >= grid.nx || b >= grid.ny || c >= grid.nz) continue;
              boundary = (grid.at(a, b, c) < 0) != in;
            }
          }
        }
        if (!boundary) continue;
        const float d = static_cast<float>(query.distance(grid.point(x, y, z).cast<float>()));
        signed_distance[grid.index(x, y, z)] = in ? -d : d;
      }
    }
  });
  grid.values = std::move(signed_distance);
  Mesh out = extract_isosurface(grid, 0.0f);
  if (noise_sigma > 0) {
    compute_vertex_normals(out);
    std::mt19937 rng(seed);
    std::normal_distribution<float> noise(0.0f, static_cast<float>(noise_sigma));
    for (std::size_t i = 0; i < out.positions.size(); ++i) out.positions[i] += noise(rng) * out.normals[i];
    out.normals.clear();
  }
  return out;
}

}  // namespace fourd
