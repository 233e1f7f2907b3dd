#pragma once
// Embree for the stages that cast rays at triangle meshes: one device for the process (creating
// one per mesh costs more than the rays) and a scene built from a mesh's arrays.
#include <embree3/rtcore.h>

#include <vector>

#include "pipeline/core/mesh.h"

namespace fourd {

// The process's Embree device. Throws Error when Embree cannot create it.
RTCDevice embree_device();

// A committed scene holding one triangle geometry (geometry id 0, primitive id = index into
// `triangles`) over `positions` (copied). The caller releases it with rtcReleaseScene. Throws
// Error when Embree cannot allocate the buffers.
RTCScene make_embree_scene(const std::vector<Vec3f>& positions, const std::vector<Tri>& triangles,
                           RTCBuildQuality quality = RTC_BUILD_QUALITY_MEDIUM);

}  // namespace fourd
