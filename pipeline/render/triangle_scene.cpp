#include "pipeline/render/triangle_scene.h"

#include <embree3/rtcore.h>

#include <limits>

#include "pipeline/render/embree_scene.h"

namespace fourd {
namespace {

RTCRay make_ray(const Eigen::Vector3f& origin, const Eigen::Vector3f& direction, float tnear,
                float tfar) {
  RTCRay ray;
  ray.org_x = origin.x();
  ray.org_y = origin.y();
  ray.org_z = origin.z();
  ray.dir_x = direction.x();
  ray.dir_y = direction.y();
  ray.dir_z = direction.z();
  ray.tnear = tnear;
  ray.tfar = tfar;
  ray.time = 0;
  ray.mask = ~0u;
  ray.id = 0;
  ray.flags = 0;
  return ray;
}

}  // namespace

struct TriangleScene::Impl {
  RTCScene scene = nullptr;
  ~Impl() {
    if (scene) rtcReleaseScene(scene);
  }
};

TriangleScene::TriangleScene(const std::vector<Vec3f>& positions, const std::vector<Tri>& triangles)
    : impl_(std::make_unique<Impl>()) {
  impl_->scene = make_embree_scene(positions, triangles);
}

TriangleScene::~TriangleScene() = default;

bool TriangleScene::occluded(const Eigen::Vector3f& origin, const Eigen::Vector3f& direction,
                             float tnear, float tfar) const {
  RTCIntersectContext context;
  rtcInitIntersectContext(&context);
  RTCRay ray = make_ray(origin, direction, tnear, tfar);
  rtcOccluded1(impl_->scene, &context, &ray);
  return ray.tfar < 0;  // Embree sets tfar to -inf when the ray is blocked
}

SceneHit TriangleScene::intersect(const Eigen::Vector3f& origin,
                                  const Eigen::Vector3f& direction) const {
  RTCIntersectContext context;
  rtcInitIntersectContext(&context);
  RTCRayHit rh;
  rh.ray = make_ray(origin, direction, 0, std::numeric_limits<float>::infinity());
  rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
  rh.hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
  rtcIntersect1(impl_->scene, &context, &rh);
  SceneHit hit;
  if (rh.hit.geomID == RTC_INVALID_GEOMETRY_ID) return hit;
  hit.face = static_cast<int>(rh.hit.primID);
  hit.bary = Eigen::Vector3f(1 - rh.hit.u - rh.hit.v, rh.hit.u, rh.hit.v);
  hit.distance = rh.ray.tfar;
  return hit;
}

}  // namespace fourd
