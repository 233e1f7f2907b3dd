#include "stages/reconstruct/raycast.h"

#include <embree3/rtcore.h>
#include <tbb/parallel_for.h>

#include <cstring>
#include <limits>

#include "pipeline/core/error.h"
#include "pipeline/render/embree_scene.h"

namespace fourd::reconstruct {

struct MeshRaycaster::Impl {
  RTCScene scene = nullptr;
  std::vector<Vec3f> positions;
  std::vector<Vec3f> face_normals;
  ~Impl() {
    if (scene) rtcReleaseScene(scene);
  }
};

MeshRaycaster::MeshRaycaster(const Mesh& mesh) : impl_(std::make_unique<Impl>()) {
  Impl& s = *impl_;
  s.positions = mesh.positions;
  s.face_normals.reserve(mesh.triangles.size());
  for (const Tri& t : mesh.triangles) {
    Vec3f n = (s.positions[t[1]] - s.positions[t[0]]).cross(s.positions[t[2]] - s.positions[t[0]]);
    float len = n.norm();
    s.face_normals.push_back(len > 0 ? Vec3f(n / len) : Vec3f::Zero());
  }
  s.scene = make_embree_scene(s.positions, mesh.triangles);
}

MeshRaycaster::~MeshRaycaster() = default;

SurfaceRender MeshRaycaster::render(const PinholeCamera& camera) const {
  SurfaceRender out;
  out.depth = cv::Mat::zeros(camera.height, camera.width, CV_32F);
  out.normal = cv::Mat::zeros(camera.height, camera.width, CV_32FC3);
  // Bounding rectangle of the vertices in front of the camera.
  double x0 = std::numeric_limits<double>::max(), y0 = x0, x1 = -x0, y1 = -x0;
  for (const Vec3f& p : impl_->positions) {
    Eigen::Vector3d c = camera.to_camera(p.cast<double>());
    if (!(c.z() > 1e-6)) continue;
    Eigen::Vector2d px = camera.pixel(c);
    x0 = std::min(x0, px.x());
    y0 = std::min(y0, px.y());
    x1 = std::max(x1, px.x());
    y1 = std::max(y1, px.y());
  }
  if (x1 < x0) return out;
  cv::Rect roi(cv::Point(static_cast<int>(std::floor(x0)) - 1, static_cast<int>(std::floor(y0)) - 1),
               cv::Point(static_cast<int>(std::ceil(x1)) + 1, static_cast<int>(std::ceil(y1)) + 1));
  roi &= cv::Rect(0, 0, camera.width, camera.height);
  if (roi.empty()) return out;

  const Eigen::Vector3f origin = camera.center().cast<float>();
  const Eigen::Matrix3d world_from_camera = camera.R.transpose();
  tbb::parallel_for(0, roi.height, [&](int i) {
    const int r = roi.y + i;
    float* depth = out.depth.ptr<float>(r);
    cv::Vec3f* normal = out.normal.ptr<cv::Vec3f>(r);
    RTCIntersectContext context;
    rtcInitIntersectContext(&context);
    for (int c = roi.x; c < roi.x + roi.width; ++c) {
      // Direction with unit z in camera coordinates: the hit distance is then the depth.
      Eigen::Vector3d dir_cam((c + 0.5 - camera.K(0, 2)) / camera.K(0, 0),
                              (r + 0.5 - camera.K(1, 2)) / camera.K(1, 1), 1.0);
      Eigen::Vector3f dir = (world_from_camera * dir_cam).cast<float>();
      RTCRayHit rh;
      rh.ray.org_x = origin.x();
      rh.ray.org_y = origin.y();
      rh.ray.org_z = origin.z();
      rh.ray.dir_x = dir.x();
      rh.ray.dir_y = dir.y();
      rh.ray.dir_z = dir.z();
      rh.ray.tnear = 0;
      rh.ray.tfar = std::numeric_limits<float>::infinity();
      rh.ray.time = 0;
      rh.ray.mask = ~0u;
      rh.ray.id = 0;
      rh.ray.flags = 0;
      rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
      rh.hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
      rtcIntersect1(impl_->scene, &context, &rh);
      if (rh.hit.geomID == RTC_INVALID_GEOMETRY_ID) continue;
      depth[c] = rh.ray.tfar;
      const Vec3f& n = impl_->face_normals[rh.hit.primID];
      normal[c] = cv::Vec3f(n.x(), n.y(), n.z());
    }
  });
  out.roi = roi;
  return out;
}

}  // namespace fourd::reconstruct
