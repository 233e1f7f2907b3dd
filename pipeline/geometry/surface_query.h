#pragma once
// Closest points on a triangle mesh (Embree BVH point queries), optionally restricted to
// triangles whose normal is compatible with the query's: registration matches a template
// vertex only to surface that faces the same way, so the front of an arm never snaps onto
// the body behind it.
#include <memory>
#include <vector>

#include "pipeline/core/mesh.h"

namespace fourd {

struct SurfaceHit {
  bool found = false;
  Vec3f point = Vec3f::Zero();   // closest point on the surface
  Vec3f normal = Vec3f::Zero();  // unit normal of the triangle it lies on
  int triangle = -1;                  // index into the input mesh's triangles
  Vec3f barycentric = Vec3f::Zero();  // of `point` in `triangle`
  float distance = 0;                 // |query - point| [m]
  float confidence = 1;               // the surface's confidence at `point` (0..1)
};

class SurfaceQuery {
 public:
  // Keeps a copy of positions, triangles and the vertices' confidence (Mesh::confidence; a hit
  // interpolates it). Degenerate triangles are skipped. A `deformable` query is for a mesh whose
  // vertices move between queries (move_vertices).
  explicit SurfaceQuery(const Mesh& mesh, bool deformable = false);
  ~SurfaceQuery();
  SurfaceQuery(const SurfaceQuery&) = delete;
  SurfaceQuery& operator=(const SurfaceQuery&) = delete;

  // Closest surface point within `max_distance` of `p`. With a non-zero `normal`, only
  // triangles whose unit normal n satisfies n . normal >= min_cos count. `near_triangle` (an
  // input triangle, e.g. the answer for where p was before it moved a little; -1: none) only
  // makes the search faster: when it counts, the answer is no farther than it, and the search
  // starts at its distance. Thread-safe.
  SurfaceHit closest(const Vec3f& p, float max_distance, const Vec3f& normal = Vec3f::Zero(),
                     float min_cos = -1.0f, int near_triangle = -1) const;

  // Moves the vertices (as many as the mesh's; the same triangles): the same answers as a new
  // query of the moved mesh, but for a deformable query at the cost of refitting the search
  // tree's boxes instead of building a new tree. A triangle degenerate where the query was made
  // stays out; one that degenerates is passed over. Not thread-safe.
  void move_vertices(const std::vector<Vec3f>& positions);

  const std::vector<Vec3f>& positions() const;
  // Confidence of the surface at its vertex i (0..1): 1 when the mesh has none.
  float vertex_confidence(std::size_t i) const;
  // The triangles it searches (the input's non-degenerate ones).
  const std::vector<Tri>& triangles() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

// Closest point to `p` on triangle (a, b, c) (Ericson, Real-Time Collision Detection 5.1.5);
// `bary` receives its barycentric coordinates.
Vec3f closest_point_on_triangle(const Vec3f& p, const Vec3f& a, const Vec3f& b, const Vec3f& c,
                                Vec3f* bary);

}  // namespace fourd
