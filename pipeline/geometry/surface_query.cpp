#include "pipeline/geometry/surface_query.h"

#include <embree3/rtcore.h>
#include <tbb/parallel_for.h>

#include <Eigen/Geometry>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>

#include "pipeline/core/error.h"
#include "pipeline/render/embree_scene.h"

namespace fourd {
namespace {

constexpr float kFirstRadius = 0.02f;  // [m]
constexpr float kRadiusGrowth = 8.0f;

// A kept triangle as the search reads it: its plane (unit normal, zero once the triangle has
// degenerated, and offset n . a), which rejects most candidates, and apart from it (so that
// rejecting reads 16 bytes) its corners, not reached through the vertex indices.
struct alignas(16) Plane {
  Vec3f normal;
  float offset;
};
struct Corners {
  Vec3f a, b, c;
};

struct QueryState {
  const std::vector<Plane>* planes;
  const std::vector<Corners>* corners;
  const std::vector<Tri>* triangles;
  const std::vector<int>* source;
  const std::vector<float>* confidence;
  Vec3f p;
  Vec3f normal;
  float min_cos;
  bool use_normal;
  SurfaceHit* hit;
};

bool point_query_callback(RTCPointQueryFunctionArguments* args) {
  auto* state = static_cast<QueryState*>(args->userPtr);
  const unsigned prim = args->primID;
  const Plane& plane = (*state->planes)[prim];
  const Vec3f& n = plane.normal;
  if (n.isZero()) return false;  // degenerated since the query was made (move_vertices)
  if (state->use_normal && n.dot(state->normal) < state->min_cos) return false;
  // Embree calls back for every triangle of a leaf whose box meets the sphere. A triangle is no
  // nearer than its plane: one that far (with a margin well above the rounding of either
  // distance, about 1e-7 m for coordinates of metres) cannot be the answer, and the exact
  // distance below is not needed.
  const float radius = args->query->radius;
  if (std::abs(n.dot(state->p) - plane.offset) > radius * (1 + 1e-4f) + 1e-6f) return false;
  const Corners& t = (*state->corners)[prim];
  Vec3f bary;
  Vec3f q = closest_point_on_triangle(state->p, t.a, t.b, t.c, &bary);
  float d = (q - state->p).norm();
  if (d >= radius) return false;
  args->query->radius = d;  // shrink the search: later candidates must be closer
  SurfaceHit& hit = *state->hit;
  hit.found = true;
  hit.point = q;
  hit.normal = n;
  hit.triangle = (*state->source)[prim];
  hit.barycentric = bary;
  hit.distance = d;
  const std::vector<float>& c = *state->confidence;
  if (!c.empty()) {
    const Tri& v = (*state->triangles)[prim];
    hit.confidence = bary[0] * c[v[0]] + bary[1] * c[v[1]] + bary[2] * c[v[2]];
  }
  return true;
}

}  // namespace

Vec3f closest_point_on_triangle(const Vec3f& p, const Vec3f& a, const Vec3f& b, const Vec3f& c,
                                Vec3f* bary) {
  const Vec3f ab = b - a, ac = c - a, ap = p - a;
  const float d1 = ab.dot(ap), d2 = ac.dot(ap);
  if (d1 <= 0 && d2 <= 0) {
    *bary = {1, 0, 0};
    return a;
  }
  const Vec3f bp = p - b;
  const float d3 = ab.dot(bp), d4 = ac.dot(bp);
  if (d3 >= 0 && d4 <= d3) {
    *bary = {0, 1, 0};
    return b;
  }
  const float vc = d1 * d4 - d3 * d2;
  if (vc <= 0 && d1 >= 0 && d3 <= 0) {
    const float v = d1 / (d1 - d3);
    *bary = {1 - v, v, 0};
    return a + v * ab;
  }
  const Vec3f cp = p - c;
  const float d5 = ab.dot(cp), d6 = ac.dot(cp);
  if (d6 >= 0 && d5 <= d6) {
    *bary = {0, 0, 1};
    return c;
  }
  const float vb = d5 * d2 - d1 * d6;
  if (vb <= 0 && d2 >= 0 && d6 <= 0) {
    const float w = d2 / (d2 - d6);
    *bary = {1 - w, 0, w};
    return a + w * ac;
  }
  const float va = d3 * d6 - d5 * d4;
  if (va <= 0 && (d4 - d3) >= 0 && (d5 - d6) >= 0) {
    const float w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
    *bary = {0, 1 - w, w};
    return b + w * (c - b);
  }
  const float denom = 1.0f / (va + vb + vc);
  const float v = vb * denom, w = vc * denom;
  *bary = {1 - v - w, v, w};
  return a + ab * v + ac * w;
}

struct SurfaceQuery::Impl {
  std::vector<Vec3f> positions;
  std::vector<Tri> triangles;  // the non-degenerate ones
  std::vector<Plane> planes;      // per kept triangle
  std::vector<Corners> corners;  // per kept triangle
  std::vector<int> source;  // index of each kept triangle in the input mesh
  std::vector<int> kept;    // per input triangle, its index among the kept ones (-1: not kept)
  std::vector<float> confidence;
  Eigen::AlignedBox3f bounds;  // of the kept triangles' vertices
  RTCScene scene = nullptr;
  ~Impl() {
    if (scene) rtcReleaseScene(scene);
  }
};

namespace {

// The corners of triangle t over `positions`.
Corners corners_of(const std::vector<Vec3f>& positions, const Tri& t) {
  return {positions[t[0]], positions[t[1]], positions[t[2]]};
}

// The plane of a triangle; a zero normal when it is degenerate.
Plane plane_of(const Corners& c) {
  const Vec3f n = (c.b - c.a).cross(c.c - c.a);
  const float len = n.norm();
  if (!(len > 0)) return {Vec3f::Zero(), 0.0f};
  const Vec3f unit = n / len;
  return {unit, unit.dot(c.a)};
}

}  // namespace

SurfaceQuery::SurfaceQuery(const Mesh& mesh, bool deformable) : impl_(std::make_unique<Impl>()) {
  Impl& s = *impl_;
  s.positions = mesh.positions;
  s.confidence = mesh.confidence;
  s.triangles.reserve(mesh.triangles.size());
  s.corners.reserve(mesh.triangles.size());
  s.planes.reserve(mesh.triangles.size());
  for (std::size_t f = 0; f < mesh.triangles.size(); ++f) {
    const Tri& t = mesh.triangles[f];
    const Corners c = corners_of(s.positions, t);
    const Plane plane = plane_of(c);
    if (plane.normal.isZero()) continue;
    s.triangles.push_back(t);
    for (int k = 0; k < 3; ++k) s.bounds.extend(s.positions[t[k]]);
    s.corners.push_back(c);
    s.planes.push_back(plane);
    s.source.push_back(static_cast<int>(f));
  }
  s.kept.assign(mesh.triangles.size(), -1);
  for (std::size_t k = 0; k < s.source.size(); ++k) s.kept[s.source[k]] = static_cast<int>(k);
  s.scene = make_embree_scene(s.positions, s.triangles, RTC_BUILD_QUALITY_MEDIUM, deformable);
}

void SurfaceQuery::move_vertices(const std::vector<Vec3f>& positions) {
  Impl& s = *impl_;
  if (positions.size() != s.positions.size()) {
    throw Error("SurfaceQuery::move_vertices: the vertex count changed");
  }
  s.positions = positions;
  tbb::parallel_for(std::size_t{0}, s.triangles.size(), [&](std::size_t f) {
    s.corners[f] = corners_of(s.positions, s.triangles[f]);
    s.planes[f] = plane_of(s.corners[f]);
  });
  s.bounds.setEmpty();
  for (const Corners& c : s.corners) s.bounds.extend(c.a).extend(c.b).extend(c.c);
  if (!s.triangles.empty()) update_embree_vertices(s.scene, s.positions);
}

SurfaceQuery::~SurfaceQuery() = default;

SurfaceHit SurfaceQuery::closest(const Vec3f& p, float max_distance, const Vec3f& normal,
                                 float min_cos, int near_triangle) const {
  SurfaceHit hit;
  if (impl_->triangles.empty()) return hit;
  QueryState state{&impl_->planes, &impl_->corners, &impl_->triangles, &impl_->source, &impl_->confidence, p, normal, min_cos, !normal.isZero(), &hit};
  // Every triangle within `radius` of p (the callback shrinks it as it finds closer ones).
  auto search = [&](float radius) {
    RTCPointQuery query;
    query.x = p.x();
    query.y = p.y();
    query.z = p.z();
    query.radius = radius;
    query.time = 0;
    RTCPointQueryContext context;
    rtcInitPointQueryContext(&context);
    rtcPointQuery(impl_->scene, &query, &context, point_query_callback, &state);
  };
  // A triangle that counts bounds the answer's distance: one search out to just past it finds
  // the answer (the same one, in the same tree order, as the growing spheres below).
  const int near = near_triangle >= 0 && near_triangle < static_cast<int>(impl_->kept.size())
                       ? impl_->kept[near_triangle]
                       : -1;
  if (near >= 0) {
    const Corners& t = impl_->corners[near];
    const Vec3f& n = impl_->planes[near].normal;
    Vec3f bary;
    const float d = (closest_point_on_triangle(p, t.a, t.b, t.c, &bary) - p).norm();
    const float bound = d * (1 + 1e-5f) + 1e-9f;
    if (!n.isZero() && !(state.use_normal && n.dot(normal) < min_cos) && bound < max_distance) {
      search(bound);
      if (hit.found) return hit;
      hit = SurfaceHit{};  // not reached: the near triangle is within the bound
    }
  }
  // Embree visits every triangle whose box meets the query sphere, in tree order, not nearest
  // first, so a large radius costs thousands of visits before the sphere shrinks (and the
  // sphere never shrinks while only normal-incompatible triangles are near). Most queries have
  // their answer within a few centimetres: search growing spheres, and stop at the first that
  // holds a hit, which is then the closest within max_distance (anything beyond the sphere is
  // farther). A sphere that holds the whole mesh is the last one needed.
  const float everything = std::sqrt(std::max((impl_->bounds.min() - p).squaredNorm(),
                                              (impl_->bounds.max() - p).squaredNorm())) +
                           impl_->bounds.diagonal().norm();
  float radius = std::min(max_distance, kFirstRadius);
  for (;;) {
    search(radius);
    if (hit.found || radius >= max_distance || radius >= everything) return hit;
    radius = std::min({max_distance, radius * kRadiusGrowth, everything});
  }
}

const std::vector<Vec3f>& SurfaceQuery::positions() const { return impl_->positions; }
const std::vector<Tri>& SurfaceQuery::triangles() const { return impl_->triangles; }
float SurfaceQuery::vertex_confidence(std::size_t i) const {
  return impl_->confidence.empty() ? 1.0f : impl_->confidence[i];
}

}  // namespace fourd
