#include "pipeline/geometry/remesh.h"

#include <Eigen/Geometry>
#include <OpenMesh/Tools/Decimater/DecimaterT.hh>
#include <OpenMesh/Tools/Decimater/ModNormalFlippingT.hh>
#include <OpenMesh/Tools/Decimater/ModQuadricT.hh>

#include <fmt/format.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <queue>
#include <limits>

#include "pipeline/core/error.h"
#include "pipeline/core/isosurface.h"
#include "pipeline/geometry/components.h"
#include "pipeline/geometry/measures.h"
#include "pipeline/geometry/openmesh_adapter.h"
#include "pipeline/geometry/surface_query.h"

namespace fourd {
namespace {

using OMesh = OpenMeshF;

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

Mesh remesh_to_vertex_count(const Mesh& mesh, int target_vertices, int iterations) {
  if (target_vertices < 12) {
    throw InputError(fmt::format("template: {} vertices is too few (at least 12)", target_vertices));
  }
  Mesh part = largest_component(mesh);
  if (part.empty()) throw InputError("template: the mesh has no triangles");
  int rejected = 0;
  OMesh om = to_openmesh<OMesh>(part, &rejected);
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

}  // namespace fourd
