#include "pipeline/geometry/measures.h"

#include <fmt/format.h>

#include <algorithm>
#include <cstdint>
#include <unordered_map>
#include <utility>

#include "pipeline/core/error.h"
#include "pipeline/geometry/components.h"
#include "pipeline/geometry/openmesh_adapter.h"

namespace fourd {
namespace {

std::uint64_t edge_key(int a, int b) {
  if (a > b) std::swap(a, b);
  return (static_cast<std::uint64_t>(static_cast<std::uint32_t>(a)) << 32) |
         static_cast<std::uint32_t>(b);
}

// How many triangles use each edge.
std::unordered_map<std::uint64_t, int> edge_face_counts(const Mesh& mesh) {
  std::unordered_map<std::uint64_t, int> edge_faces;
  edge_faces.reserve(mesh.triangles.size() * 2);
  for (const Tri& t : mesh.triangles) {
    for (int k = 0; k < 3; ++k) ++edge_faces[edge_key(t[k], t[(k + 1) % 3])];
  }
  return edge_faces;
}

}  // namespace

double surface_area(const Mesh& mesh) {
  double area = 0;
  for (const Tri& t : mesh.triangles) area += triangle_area(mesh, t);
  return area;
}

double enclosed_volume(const Mesh& mesh) {
  double six_volume = 0;
  for (const Tri& t : mesh.triangles) {
    const Eigen::Vector3d a = mesh.positions[t[0]].cast<double>(),
                          b = mesh.positions[t[1]].cast<double>(),
                          c = mesh.positions[t[2]].cast<double>();
    six_volume += a.dot(b.cross(c));
  }
  return six_volume / 6;
}

std::vector<std::vector<int>> edge_neighbours(const Mesh& mesh) {
  std::vector<std::vector<int>> rings(mesh.num_vertices());
  for (const Tri& t : mesh.triangles) {
    for (int k = 0; k < 3; ++k) {
      rings[t[k]].push_back(t[(k + 1) % 3]);
      rings[t[k]].push_back(t[(k + 2) % 3]);
    }
  }
  for (auto& ring : rings) {
    std::sort(ring.begin(), ring.end());
    ring.erase(std::unique(ring.begin(), ring.end()), ring.end());
  }
  return rings;
}

std::vector<std::vector<int>> vertex_neighbours(const Mesh& mesh) {
  int rejected = 0;
  OpenMeshF om = to_openmesh<OpenMeshF>(mesh, &rejected);
  if (rejected > 0) {
    throw InputError(fmt::format("mesh: {} triangles are not manifold", rejected));
  }
  std::vector<std::vector<int>> rings(mesh.num_vertices());
  for (auto v : om.vertices()) {
    for (auto w : om.vv_range(v)) rings[v.idx()].push_back(w.idx());
  }
  return rings;
}

int count_boundary_edges(const Mesh& mesh) {
  int n = 0;
  for (const auto& [key, count] : edge_face_counts(mesh)) n += count == 1;
  return n;
}

ManifoldReport check_manifold(const Mesh& mesh) {
  ManifoldReport report;
  const std::unordered_map<std::uint64_t, int> edge_faces = edge_face_counts(mesh);
  for (const auto& [key, count] : edge_faces) {
    if (count > 2) ++report.non_manifold_edges;
    if (count == 1) ++report.boundary_edges;
  }
  report.components = count_components(mesh);
  to_openmesh<OpenMeshF>(mesh, &report.rejected_faces);
  if (report.manifold() && report.boundary_edges == 0) {
    // Euler: V - E + F = 2 (components - handles), over the vertices the triangles use.
    std::vector<char> used(mesh.num_vertices(), 0);
    for (const Tri& t : mesh.triangles) used[t[0]] = used[t[1]] = used[t[2]] = 1;
    const long euler = static_cast<long>(std::count(used.begin(), used.end(), 1)) -
                       static_cast<long>(edge_faces.size()) +
                       static_cast<long>(mesh.triangles.size());
    report.handles = static_cast<int>((2L * report.components - euler) / 2);
  }
  return report;
}

}  // namespace fourd
