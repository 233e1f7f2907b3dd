#include "pipeline/geometry/decimate.h"

#include <OpenMesh/Tools/Decimater/DecimaterT.hh>
#include <OpenMesh/Tools/Decimater/McDecimaterT.hh>
#include <OpenMesh/Tools/Decimater/ModNormalFlippingT.hh>
#include <OpenMesh/Tools/Decimater/ModQuadricT.hh>

#include <cstdlib>
#include <mutex>

#include "pipeline/geometry/openmesh_adapter.h"

namespace fourd {
namespace {

struct Traits : OpenMesh::DefaultTraits {
  using Point = OpenMesh::Vec3d;  // quadrics in double precision
  VertexAttributes(OpenMesh::Attributes::Status);
  EdgeAttributes(OpenMesh::Attributes::Status);
  HalfedgeAttributes(OpenMesh::Attributes::Status | OpenMesh::Attributes::PrevHalfedge);
  FaceAttributes(OpenMesh::Attributes::Status | OpenMesh::Attributes::Normal);
};
using OMesh = OpenMesh::TriMesh_ArrayKernelT<Traits>;

// Collapses edges of `om` by quadric error with a decimater of type `D` until `vertices` remain.
template <class D>
void collapse_to(OMesh& om, std::size_t vertices, double max_normal_deviation_deg) {
  D decimater(om);
  OpenMesh::Decimater::ModQuadricT<OMesh>::Handle quadric;
  OpenMesh::Decimater::ModNormalFlippingT<OMesh>::Handle flipping;
  decimater.add(quadric);
  decimater.module(quadric).unset_max_err();
  if (max_normal_deviation_deg > 0) {
    decimater.add(flipping);
    decimater.module(flipping).set_max_normal_deviation(max_normal_deviation_deg);
  }
  decimater.initialize();
  decimater.decimate_to(vertices);
  om.garbage_collection();
}

}  // namespace

Mesh decimate(const Mesh& mesh, int target_vertices, double max_normal_deviation_deg) {
  if (target_vertices <= 0 || static_cast<int>(mesh.positions.size()) <= target_vertices) {
    return mesh;
  }
  OMesh om = to_openmesh<OMesh>(mesh);
  om.update_face_normals();

  // Down to a few times the target by the multiple-choice decimater (the best of a few random
  // collapses at a time: fast on a fine isosurface), the rest by the exact one (the collapse
  // of least error first), whose choices shape the result. The multiple-choice decimater draws
  // its candidates from the C library's rand(), one state for the whole process: it is seeded
  // and run one mesh at a time, so that a mesh does not depend on which meshes are decimated
  // beside it (frames are reconstructed in parallel).
  const std::size_t fast_until = static_cast<std::size_t>(target_vertices) * 3;
  if (om.n_vertices() > fast_until) {
    static std::mutex rand_state;
    const std::lock_guard<std::mutex> lock(rand_state);
    std::srand(1);
    collapse_to<OpenMesh::Decimater::McDecimaterT<OMesh>>(om, fast_until, max_normal_deviation_deg);
  }
  collapse_to<OpenMesh::Decimater::DecimaterT<OMesh>>(
      om, static_cast<std::size_t>(target_vertices), max_normal_deviation_deg);

  // Vertices without a face (of input faces OpenMesh refused) are left out: remeshing would
  // trip over them.
  return from_openmesh(om, IsolatedVertices::kDrop);
}

}  // namespace fourd
