#include "pipeline/render/embree_scene.h"

#include <cstring>

#include "pipeline/core/error.h"

namespace fourd {

RTCDevice embree_device() {
  static RTCDevice device = [] {
    RTCDevice d = rtcNewDevice(nullptr);
    if (!d) throw Error("cannot create the Embree device");
    return d;
  }();
  return device;
}

namespace {

void copy_positions(const std::vector<Vec3f>& positions, float* vb) {
  for (std::size_t i = 0; i < positions.size(); ++i) {
    std::memcpy(vb + 3 * i, positions[i].data(), 3 * sizeof(float));
  }
}

}  // namespace

RTCScene make_embree_scene(const std::vector<Vec3f>& positions, const std::vector<Tri>& triangles,
                           RTCBuildQuality quality, bool refit) {
  RTCDevice device = embree_device();
  RTCScene scene = rtcNewScene(device);
  // The geometry's own build quality (refit) counts only in a two-level scene, which a scene of
  // low quality is.
  rtcSetSceneBuildQuality(scene, refit ? RTC_BUILD_QUALITY_LOW : quality);
  if (refit) rtcSetSceneFlags(scene, RTC_SCENE_FLAG_DYNAMIC);
  if (!triangles.empty()) {
    RTCGeometry geom = rtcNewGeometry(device, RTC_GEOMETRY_TYPE_TRIANGLE);
    if (refit) rtcSetGeometryBuildQuality(geom, RTC_BUILD_QUALITY_REFIT);
    auto* vb = static_cast<float*>(rtcSetNewGeometryBuffer(
        geom, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3, 3 * sizeof(float), positions.size()));
    auto* ib = static_cast<unsigned*>(rtcSetNewGeometryBuffer(
        geom, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3, 3 * sizeof(unsigned), triangles.size()));
    if (!vb || !ib) {
      rtcReleaseGeometry(geom);
      rtcReleaseScene(scene);
      throw Error("Embree could not allocate mesh buffers");
    }
    copy_positions(positions, vb);
    for (std::size_t f = 0; f < triangles.size(); ++f) {
      for (int k = 0; k < 3; ++k) ib[3 * f + k] = static_cast<unsigned>(triangles[f][k]);
    }
    rtcCommitGeometry(geom);
    rtcAttachGeometry(scene, geom);
    rtcReleaseGeometry(geom);
  }
  rtcCommitScene(scene);
  return scene;
}

void update_embree_vertices(RTCScene scene, const std::vector<Vec3f>& positions) {
  RTCGeometry geom = rtcGetGeometry(scene, 0);
  if (!geom) return;  // a scene without triangles
  copy_positions(positions,
                 static_cast<float*>(rtcGetGeometryBufferData(geom, RTC_BUFFER_TYPE_VERTEX, 0)));
  rtcUpdateGeometryBuffer(geom, RTC_BUFFER_TYPE_VERTEX, 0);
  rtcCommitGeometry(geom);
  rtcCommitScene(scene);
}

}  // namespace fourd
