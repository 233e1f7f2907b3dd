#include "stages/align/mesh_tools.h"

#include <Eigen/Geometry>
#include <OpenMesh/Core/IO/MeshIO.hh>
#include <OpenMesh/Core/Mesh/TriMesh_ArrayKernelT.hh>
#include <OpenMesh/Core/System/omstream.hh>
#include <OpenMesh/Tools/Decimater/DecimaterT.hh>
#include <OpenMesh/Tools/Decimater/ModNormalFlippingT.hh>
#include <OpenMesh/Tools/Decimater/ModQuadricT.hh>

#include <fmt/format.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <numeric>
#include <queue>
#include <limits>
#include <unordered_map>

#include "pipeline/core/error.h"
#include "pipeline/core/isosurface.h"
#include "pipeline/geometry/mesh_volume.h"
#include "stages/align/surface_query.h"

namespace fourd::align {
namespace {

using OMesh = OpenMesh::TriMesh_ArrayKernelT<>;

// OpenMesh reports rejected faces on its own error stream; library code prints nothing, and
// check_manifold() counts them instead.
void silence_openmesh() {
  static const bool done = [] {
    omerr().disable();
    omlog().disable();
    return true;
  }();
  (void)done;
}

std::uint64_t edge_key(int a, int b) {
  if (a > b) std::swap(a, b);
  return (static_cast<std::uint64_t>(static_cast<std::uint32_t>(a)) << 32) |
         static_cast<std::uint32_t>(b);
}

struct UnionFind {
  std::vector<int> parent;
  explicit UnionFind(std::size_t n) : parent(n) { std::iota(parent.begin(), parent.end(), 0); }
  int find(int x) {
    while (parent[x] != x) x = parent[x] = parent[parent[x]];
    return x;
  }
  void unite(int a, int b) { parent[find(a)] = find(b); }
};

bool degenerate_indices(const Tri& t) { return t[0] == t[1] || t[1] == t[2] || t[0] == t[2]; }

// Builds a halfedge mesh; triangles it cannot hold are counted in *rejected.
OMesh to_openmesh(const Mesh& mesh, int* rejected) {
  silence_openmesh();
  OMesh om;
  std::vector<OMesh::VertexHandle> handles;
  handles.reserve(mesh.num_vertices());
  for (const Vec3f& p : mesh.positions) handles.push_back(om.add_vertex({p.x(), p.y(), p.z()}));
  int bad = 0;
  for (const Tri& t : mesh.triangles) {
    if (degenerate_indices(t) || !om.add_face(handles[t[0]], handles[t[1]], handles[t[2]]).is_valid()) {
      ++bad;
    }
  }
  if (rejected) *rejected = bad;
  return om;
}

Mesh from_openmesh(OMesh& om) {
  om.garbage_collection();
  Mesh mesh;
  mesh.positions.reserve(om.n_vertices());
  for (auto v : om.vertices()) {
    const auto& p = om.point(v);
    mesh.positions.emplace_back(p[0], p[1], p[2]);
  }
  mesh.triangles.reserve(om.n_faces());
  for (auto f : om.faces()) {
    Tri t;
    int k = 0;
    for (auto v : om.fv_range(f)) t[k++] = v.idx();
    mesh.triangles.push_back(t);
  }
  return mesh;
}

Vec3f to_eigen(const OMesh::Point& p) { return {p[0], p[1], p[2]}; }
OMesh::Point to_om(const Vec3f& p) { return {p.x(), p.y(), p.z()}; }

float edge_length(const OMesh& om, OMesh::EdgeHandle e) {
  auto h = om.halfedge_handle(e, 0);
  return (om.point(om.to_vertex_handle(h)) - om.point(om.from_vertex_handle(h))).norm();
}

void split_long_edges(OMesh& om, float high) {
  for (std::size_t i = 0; i < om.n_edges(); ++i) {  // new edges are appended and visited too
    OMesh::EdgeHandle e(static_cast<int>(i));
    if (om.status(e).deleted() || edge_length(om, e) <= high) continue;
    auto h = om.halfedge_handle(e, 0);
    OMesh::Point mid = 0.5f * (om.point(om.to_vertex_handle(h)) + om.point(om.from_vertex_handle(h)));
    om.split(e, mid);
  }
}

void collapse_short_edges(OMesh& om, float low, float high) {
  for (std::size_t i = 0; i < om.n_edges(); ++i) {
    OMesh::EdgeHandle e(static_cast<int>(i));
    if (om.status(e).deleted() || om.is_boundary(e) || edge_length(om, e) >= low) continue;
    auto h = om.halfedge_handle(e, 0);
    auto from = om.from_vertex_handle(h), to = om.to_vertex_handle(h);
    if (om.is_boundary(from)) {
      if (om.is_boundary(to)) continue;
      h = om.opposite_halfedge_handle(h);
      std::swap(from, to);
    }
    // Collapsing `from` into `to` must not create an edge longer than `high`.
    bool too_long = false;
    for (auto n : om.vv_range(from)) {
      if ((om.point(n) - om.point(to)).norm() > high) {
        too_long = true;
        break;
      }
    }
    if (too_long || !om.is_collapse_ok(h)) continue;
    om.collapse(h);
  }
  om.garbage_collection();
}

int target_valence(const OMesh& om, OMesh::VertexHandle v) { return om.is_boundary(v) ? 4 : 6; }

// Flips edges that bring the four vertices involved closer to their ideal valence, unless the
// flip would fold the surface.
void equalize_valences(OMesh& om) {
  for (auto e : om.edges()) {
    if (om.is_boundary(e) || !om.is_flip_ok(e)) continue;
    auto h0 = om.halfedge_handle(e, 0), h1 = om.halfedge_handle(e, 1);
    auto a = om.to_vertex_handle(h0), b = om.to_vertex_handle(h1);
    auto c = om.to_vertex_handle(om.next_halfedge_handle(h0));
    auto d = om.to_vertex_handle(om.next_halfedge_handle(h1));
    auto dev = [&](OMesh::VertexHandle v, int delta) {
      return std::abs(static_cast<int>(om.valence(v)) + delta - target_valence(om, v));
    };
    int before = dev(a, 0) + dev(b, 0) + dev(c, 0) + dev(d, 0);
    int after = dev(a, -1) + dev(b, -1) + dev(c, 1) + dev(d, 1);
    if (after >= before) continue;
    // The new triangles (c, d, a)... must face the same way as the old ones.
    const Vec3f pa = to_eigen(om.point(a)), pb = to_eigen(om.point(b)), pc = to_eigen(om.point(c)),
                pd = to_eigen(om.point(d));
    Vec3f old_n = (pb - pa).cross(pc - pa) + (pa - pb).cross(pd - pb);
    Vec3f n1 = (pd - pc).cross(pa - pc), n2 = (pc - pd).cross(pb - pd);
    if (n1.dot(old_n) <= 0 || n2.dot(old_n) <= 0) continue;
    om.flip(e);
  }
}

// Moves every interior vertex towards its neighbours' centroid within its tangent plane, then
// projects all vertices back onto the reference surface.
void relax_and_project(OMesh& om, const SurfaceQuery& reference) {
  om.update_face_normals();
  om.update_vertex_normals();
  std::vector<OMesh::Point> moved(om.n_vertices());
  for (auto v : om.vertices()) {
    moved[v.idx()] = om.point(v);
    if (om.is_boundary(v) || om.valence(v) == 0) continue;
    OMesh::Point centroid(0, 0, 0);
    int n = 0;
    for (auto w : om.vv_range(v)) {
      centroid += om.point(w);
      ++n;
    }
    centroid /= static_cast<float>(n);
    OMesh::Point delta = centroid - om.point(v);
    const OMesh::Normal& normal = om.normal(v);
    delta -= normal * OpenMesh::dot(normal, delta);
    moved[v.idx()] = om.point(v) + delta;
  }
  for (auto v : om.vertices()) {
    SurfaceHit hit = reference.closest(to_eigen(moved[v.idx()]), 1e3f);
    om.set_point(v, hit.found ? to_om(hit.point) : moved[v.idx()]);
  }
}

void request_status(OMesh& om) {
  om.request_vertex_status();
  om.request_edge_status();
  om.request_face_status();
  om.request_face_normals();
  om.request_vertex_normals();
}

}  // namespace

ManifoldReport check_manifold(const Mesh& mesh) {
  ManifoldReport report;
  std::unordered_map<std::uint64_t, int> edge_faces;
  edge_faces.reserve(mesh.triangles.size() * 2);
  UnionFind components(mesh.num_vertices());
  for (const Tri& t : mesh.triangles) {
    for (int k = 0; k < 3; ++k) {
      ++edge_faces[edge_key(t[k], t[(k + 1) % 3])];
      components.unite(t[k], t[(k + 1) % 3]);
    }
  }
  for (const auto& [key, count] : edge_faces) {
    if (count > 2) ++report.non_manifold_edges;
    if (count == 1) ++report.boundary_edges;
  }
  std::vector<char> root_seen(mesh.num_vertices(), 0);
  for (const Tri& t : mesh.triangles) {
    int r = components.find(t[0]);
    if (!root_seen[r]) {
      root_seen[r] = 1;
      ++report.components;
    }
  }
  to_openmesh(mesh, &report.rejected_faces);
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

double surface_area(const Mesh& mesh) {
  double area = 0;
  for (const Tri& t : mesh.triangles) {
    const Vec3f& a = mesh.positions[t[0]];
    area += 0.5 * (mesh.positions[t[1]] - a).cross(mesh.positions[t[2]] - a).norm();
  }
  return area;
}


Mesh largest_component(const Mesh& mesh) {
  UnionFind uf(mesh.num_vertices());
  for (const Tri& t : mesh.triangles) {
    uf.unite(t[0], t[1]);
    uf.unite(t[1], t[2]);
  }
  std::unordered_map<int, double> area;
  for (const Tri& t : mesh.triangles) {
    const Vec3f& a = mesh.positions[t[0]];
    area[uf.find(t[0])] += (mesh.positions[t[1]] - a).cross(mesh.positions[t[2]] - a).norm();
  }
  if (area.empty()) return {};
  int best = std::max_element(area.begin(), area.end(), [](const auto& x, const auto& y) {
               return x.second < y.second;
             })->first;
  Mesh out;
  std::vector<int> remap(mesh.num_vertices(), -1);
  for (const Tri& t : mesh.triangles) {
    if (uf.find(t[0]) != best) continue;
    Tri nt;
    for (int k = 0; k < 3; ++k) {
      int& r = remap[t[k]];
      if (r < 0) {
        r = static_cast<int>(out.positions.size());
        out.positions.push_back(mesh.positions[t[k]]);
      }
      nt[k] = r;
    }
    out.triangles.push_back(nt);
  }
  return out;
}

Mesh remesh_to_vertex_count(const Mesh& mesh, int target_vertices, int iterations) {
  if (target_vertices < 12) {
    throw InputError(fmt::format("template: {} vertices is too few (at least 12)", target_vertices));
  }
  Mesh part = largest_component(mesh);
  if (part.empty()) throw InputError("template: the mesh has no triangles");
  int rejected = 0;
  OMesh om = to_openmesh(part, &rejected);
  if (rejected > 0) {
    throw InputError(fmt::format(
        "template: {} triangles of the mesh are not manifold (a halfedge mesh cannot hold them)",
        rejected));
  }
  request_status(om);
  const SurfaceQuery reference(part);

  // A closed mesh of near-equilateral triangles of edge L has about 2 A / (sqrt(3) L^2)
  // vertices. Aim a little above the target: decimation removes the excess precisely.
  const double area = surface_area(part);
  const double aim = 1.04 * target_vertices;
  auto length_for = [&](double vertices) { return std::sqrt(2 * area / (std::sqrt(3.0) * vertices)); };
  float length = static_cast<float>(length_for(aim));
  auto remesh_pass = [&](int passes) {
    for (int i = 0; i < passes; ++i) {
      split_long_edges(om, 4.0f / 3.0f * length);
      collapse_short_edges(om, 4.0f / 5.0f * length, 4.0f / 3.0f * length);
      equalize_valences(om);
      relax_and_project(om, reference);
    }
  };
  remesh_pass(iterations);
  // Correct the edge length once from the count reached (the surface is not flat).
  const double reached = static_cast<double>(om.n_vertices());
  if (reached < target_vertices || reached > 1.1 * target_vertices) {
    length = static_cast<float>(length * std::sqrt(reached / aim));
    remesh_pass(std::max(3, iterations / 2));
  }

  const auto target = static_cast<std::size_t>(target_vertices);
  if (om.n_vertices() > target) {
    OpenMesh::Decimater::DecimaterT<OMesh> decimater(om);
    OpenMesh::Decimater::ModQuadricT<OMesh>::Handle quadric;
    OpenMesh::Decimater::ModNormalFlippingT<OMesh>::Handle no_flips;
    decimater.add(quadric);
    decimater.add(no_flips);
    decimater.module(quadric).unset_max_err();
    decimater.initialize();
    decimater.decimate_to(target);
    om.garbage_collection();
  }
  while (om.n_vertices() < target) {
    // Split the longest edge: one vertex more each time.
    OMesh::EdgeHandle longest;
    float best = -1;
    for (auto e : om.edges()) {
      float l = edge_length(om, e);
      if (l > best) {
        best = l;
        longest = e;
      }
    }
    auto h = om.halfedge_handle(longest, 0);
    om.split(longest, 0.5f * (om.point(om.to_vertex_handle(h)) + om.point(om.from_vertex_handle(h))));
  }
  for (int i = 0; i < 3; ++i) {
    equalize_valences(om);
    relax_and_project(om, reference);
  }
  Mesh out = from_openmesh(om);
  if (static_cast<int>(out.num_vertices()) != target_vertices) {
    throw SolverError(fmt::format("template: remeshing reached {} vertices instead of {}",
                                  out.num_vertices(), target_vertices));
  }
  return out;
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
  for (int r = 1; r <= max_radius; ++r) {
    solid.inside = morphology(solid, morphology(solid, inside, true, r), false, r);  // close
    solid.inside = morphology(solid, morphology(solid, solid.inside, false, r), true, r);  // open
    const Mesh surface = surface_of_solid(mesh, solid);
    Mesh part = largest_component(surface);
    // Opening must not cut off or erase a limb: no piece of note apart from the body, and
    // the body's volume kept.
    const double volume = enclosed_volume(part);
    if (volume < 0.995 * enclosed_volume(surface) || volume < min_volume * input_volume) continue;
    const int handles = check_manifold(part).handles;
    if (handles >= 0 && handles < best_handles) {
      best = std::move(part);
      best_handles = handles;
      if (handles == 0) break;
    }
  }
  return best;
}

std::vector<std::vector<int>> vertex_neighbours(const Mesh& mesh) {
  int rejected = 0;
  OMesh om = to_openmesh(mesh, &rejected);
  if (rejected > 0) {
    throw InputError(fmt::format("mesh: {} triangles are not manifold", rejected));
  }
  std::vector<std::vector<int>> rings(mesh.num_vertices());
  for (auto v : om.vertices()) {
    for (auto w : om.vv_range(v)) rings[v.idx()].push_back(w.idx());
  }
  return rings;
}

std::vector<int> geodesic_update(const Mesh& mesh, const std::vector<std::vector<int>>& rings,
                                 int source, int source_id, double radius,
                                 std::vector<double>& dist, std::vector<int>& owner) {
  using Item = std::pair<double, int>;
  std::priority_queue<Item, std::vector<Item>, std::greater<>> heap;
  std::vector<int> reached;
  if (dist[source] > 0) {
    dist[source] = 0;
    owner[source] = source_id;
  }
  heap.emplace(0.0, source);
  reached.push_back(source);
  while (!heap.empty()) {
    auto [d, v] = heap.top();
    heap.pop();
    if (d > dist[v]) continue;
    for (int w : rings[v]) {
      const double nd = d + (mesh.positions[v] - mesh.positions[w]).cast<double>().norm();
      if (nd < dist[w] && nd <= radius) {
        if (dist[w] == std::numeric_limits<double>::infinity()) reached.push_back(w);
        dist[w] = nd;
        owner[w] = source_id;
        heap.emplace(nd, w);
      }
    }
  }
  return reached;
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

}  // namespace fourd::align
