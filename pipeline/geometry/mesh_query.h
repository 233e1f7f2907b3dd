#pragma once
// Exact closest-point and line-crossing queries on one triangle mesh (CGAL AABB tree over its
// non-degenerate triangles; the mesh need not be manifold): the remesher puts vertices back on
// the surface with it, the validators measure with it. Built once, then queried from any number
// of threads.
#include <memory>
#include <vector>

#include "pipeline/core/mesh.h"

namespace fourd {

struct ClosestPoint {
  Vec3f point = Vec3f::Zero();
  int triangle = -1;                      // index into the mesh's triangles
  Vec3f barycentric = Vec3f(1, 0, 0);     // of `point` in that triangle
  double distance = 0;                    // [m]
};

class MeshQuery {
 public:
  // Throws InputError when the mesh has no non-degenerate triangle.
  explicit MeshQuery(const Mesh& mesh);
  ~MeshQuery();
  MeshQuery(const MeshQuery&) = delete;
  MeshQuery& operator=(const MeshQuery&) = delete;

  ClosestPoint closest(const Vec3f& p) const;
  double distance(const Vec3f& p) const;
  // Where the line through (0, y, z) along +x crosses the surface, sorted by x; direction is
  // +1 where the line enters the solid (the triangle faces -x, outward normals assumed) and -1
  // where it leaves. Summed up to a point, the winding number: for closed surfaces that may
  // overlap one another (a garment over a body), a point is inside their union where it is
  // not 0, where the parity of the crossings would call the overlap outside.
  struct Crossing {
    double x;
    int direction;
  };
  std::vector<Crossing> crossings_along_x(double y, double z) const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

// The point with barycentric coordinates `b` in triangle `t` of `mesh`.
inline Vec3f barycentric_point(const Mesh& mesh, int t, const Vec3f& b) {
  const Tri& tri = mesh.triangles[t];
  return b.x() * mesh.positions[tri[0]] + b.y() * mesh.positions[tri[1]] +
         b.z() * mesh.positions[tri[2]];
}

}  // namespace fourd
