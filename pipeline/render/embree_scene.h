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
// Error when Embree cannot allocate the buffers. A `refit` scene is built for moving vertices:
// its BVH keeps its topology and only has its boxes refitted when the vertex buffer changes
// (update_embree_vertices); `quality` is then ignored.
RTCScene make_embree_scene(const std::vector<Vec3f>& positions, const std::vector<Tri>& triangles,
                           RTCBuildQuality quality = RTC_BUILD_QUALITY_MEDIUM, bool refit = false);

// Moves the vertices of a scene make_embree_scene built (as many as it was given) and commits
// it: a refit scene's BVH is refitted, another's rebuilt.
void update_embree_vertices(RTCScene scene, const std::vector<Vec3f>& positions);

}  // namespace fourd
