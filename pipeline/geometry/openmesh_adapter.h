#pragma once
// Mesh <-> OpenMesh halfedge triangle meshes (of any traits: float or double points). Includes
// OpenMesh's mesh headers: for the .cpp files that run OpenMesh's algorithms (decimation,
// remeshing, one-rings), not for headers.
#include <OpenMesh/Core/Mesh/TriMesh_ArrayKernelT.hh>

#include <vector>

#include "pipeline/core/mesh.h"

namespace fourd {

// OpenMesh's default triangle mesh (float points, no status attributes until requested).
using OpenMeshF = OpenMesh::TriMesh_ArrayKernelT<>;

// Turns off OpenMesh's own error and log streams (it reports every face it refuses on them;
// library code prints nothing, and to_openmesh() counts those faces instead). Idempotent.
void silence_openmesh();

// A halfedge mesh of `mesh`'s positions (#V vertices, same order) and triangles. Triangles that
// repeat a vertex, or that the halfedge structure refuses (non-manifold edge or vertex,
// duplicated triangle), are left out and counted in `*rejected` (if given).
template <class OM>
OM to_openmesh(const Mesh& mesh, int* rejected = nullptr) {
  silence_openmesh();
  OM om;
  std::vector<typename OM::VertexHandle> handles;
  handles.reserve(mesh.num_vertices());
  for (const Vec3f& p : mesh.positions) {
    handles.push_back(om.add_vertex(typename OM::Point(p.x(), p.y(), p.z())));
  }
  int bad = 0;
  for (const Tri& t : mesh.triangles) {
    if (t[0] == t[1] || t[1] == t[2] || t[0] == t[2] ||
        !om.add_face(handles[t[0]], handles[t[1]], handles[t[2]]).is_valid()) {
      ++bad;
    }
  }
  if (rejected) *rejected = bad;
  return om;
}

enum class IsolatedVertices { kKeep, kDrop };

// The mesh of `om` after its garbage collection (when it has vertex status): vertices in
// OpenMesh's order, without those no face uses if `isolated` is kDrop; positions and triangles.
template <class OM>
Mesh from_openmesh(OM& om, IsolatedVertices isolated = IsolatedVertices::kKeep) {
  if (om.has_vertex_status()) om.garbage_collection();
  Mesh mesh;
  std::vector<int> index(om.n_vertices(), -1);
  mesh.positions.reserve(om.n_vertices());
  for (auto v : om.vertices()) {
    if (isolated == IsolatedVertices::kDrop && om.is_isolated(v)) continue;
    index[v.idx()] = static_cast<int>(mesh.positions.size());
    const auto& p = om.point(v);
    mesh.positions.emplace_back(static_cast<float>(p[0]), static_cast<float>(p[1]),
                                static_cast<float>(p[2]));
  }
  mesh.triangles.reserve(om.n_faces());
  for (auto f : om.faces()) {
    Tri t;
    int k = 0;
    for (auto v : om.fv_range(f)) {
      if (k < 3) t[k] = index[v.idx()];
      ++k;
    }
    if (k == 3) mesh.triangles.push_back(t);
  }
  return mesh;
}

}  // namespace fourd
