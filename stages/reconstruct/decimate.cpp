#include "stages/reconstruct/decimate.h"

#include <OpenMesh/Core/Mesh/TriMesh_ArrayKernelT.hh>
#include <OpenMesh/Tools/Decimater/DecimaterT.hh>
#include <OpenMesh/Tools/Decimater/ModNormalFlippingT.hh>
#include <OpenMesh/Tools/Decimater/ModQuadricT.hh>

namespace fourd::reconstruct {
namespace {

struct Traits : OpenMesh::DefaultTraits {
  using Point = OpenMesh::Vec3d;  // quadrics in double precision
  VertexAttributes(OpenMesh::Attributes::Status);
  EdgeAttributes(OpenMesh::Attributes::Status);
  HalfedgeAttributes(OpenMesh::Attributes::Status | OpenMesh::Attributes::PrevHalfedge);
  FaceAttributes(OpenMesh::Attributes::Status | OpenMesh::Attributes::Normal);
};
using OMesh = OpenMesh::TriMesh_ArrayKernelT<Traits>;

}  // namespace

Mesh decimate(const Mesh& mesh, int target_vertices, double max_normal_deviation_deg) {
  if (target_vertices <= 0 || static_cast<int>(mesh.positions.size()) <= target_vertices) {
    return mesh;
  }
  OMesh om;
  std::vector<OMesh::VertexHandle> v;
  v.reserve(mesh.positions.size());
  for (const Vec3f& p : mesh.positions) v.push_back(om.add_vertex(OMesh::Point(p.x(), p.y(), p.z())));
  for (const Tri& t : mesh.triangles) om.add_face(v[t[0]], v[t[1]], v[t[2]]);
  om.update_face_normals();

  using Decimater = OpenMesh::Decimater::DecimaterT<OMesh>;
  Decimater decimater(om);
  OpenMesh::Decimater::ModQuadricT<OMesh>::Handle quadric;
  OpenMesh::Decimater::ModNormalFlippingT<OMesh>::Handle flipping;
  decimater.add(quadric);
  decimater.module(quadric).unset_max_err();
  if (max_normal_deviation_deg > 0) {
    decimater.add(flipping);
    decimater.module(flipping).set_max_normal_deviation(max_normal_deviation_deg);
  }
  decimater.initialize();
  decimater.decimate_to(static_cast<std::size_t>(target_vertices));
  om.garbage_collection();

  // Vertices without a face (of input faces OpenMesh refused) are left out: remeshing would
  // trip over them.
  Mesh out;
  std::vector<int> index(om.n_vertices(), -1);
  out.positions.reserve(om.n_vertices());
  for (auto vh : om.vertices()) {
    if (om.is_isolated(vh)) continue;
    index[vh.idx()] = static_cast<int>(out.positions.size());
    const auto& p = om.point(vh);
    out.positions.emplace_back(static_cast<float>(p[0]), static_cast<float>(p[1]),
                               static_cast<float>(p[2]));
  }
  out.triangles.reserve(om.n_faces());
  for (auto fh : om.faces()) {
    Tri t;
    int k = 0;
    for (auto vh : om.fv_range(fh)) {
      if (k < 3) t[k] = index[vh.idx()];
      ++k;
    }
    if (k == 3) out.triangles.push_back(t);
  }
  return out;
}

}  // namespace fourd::reconstruct
