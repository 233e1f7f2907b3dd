#pragma once
// The procedural quadruped (character.body quadruped): its implicit body, texture charts and
// coat. It is meshed, skinned and posed like the human performer (character.cpp); only its
// shape, skeleton, charts and colours are its own. Internal to the synth stage.
//
// A hoofed animal, standing at rest facing +x on all four hooves: a trunk of three joints
// (pelvis, the root, over the hips; spine; chest, over the shoulders), a neck and head, a tail
// of three joints held out behind, and four legs of four segments each: front legs
// upper_arm_{l,r} (shoulder), forearm (elbow), front_cannon (knee), front_hoof (fetlock: the
// pastern and hoof); hind legs thigh_{l,r} (hip), shin (stifle), hind_cannon (hock), hind_hoof
// (fetlock). At rest every joint frame is axis-aligned with the world.
#include <Eigen/Core>
#include <cstdint>
#include <opencv2/core.hpp>
#include <optional>
#include <vector>

#include "pipeline/core/mesh.h"
#include "stages/synth/body_model.h"

namespace fourd::synth::detail {

// The hoof, an ellipsoid carried by the hoof joint (at the fetlock) whose bottom touches the
// floor at rest: its centre relative to the fetlock and its semi-axes (along x, y, z at rest),
// for a fetlock `fetlock_height` above the floor at rest. The gaits keep it above the floor.
struct HoofShape {
  Eigen::Vector3d centre;
  Eigen::Vector3d radii;
};
HoofShape hoof_shape(double fetlock_height);

// The quadruped's body at a nominal size whose highest point (the ears' tips) is `height` above
// the floor (the final mesh is scaled to it exactly), `build` its girth relative to the
// average. No randomness.
BodyModel make_quadruped_model(double height, double build);

// Texture coordinates of every rest-pose vertex: each in the chart of the body part carrying
// most of its weight (`dense`: #V x #joints skinning weights) — the trunk, the head and neck,
// the tail, a front or a hind leg (left and right share theirs).
std::vector<Vec2f> quadruped_uvs(const BodyModel& body, const Mesh& mesh, const Eigen::MatrixXd& dense);

// The coat (CV_8UC3, BGR) for those charts: a colour and markings from the seed (never near
// green, the default backdrop's colour, nor near the studio's `key`), a lighter belly, a darker
// mane, tail and muzzle, dark hooves, eyes; fine noise everywhere for stereo.
cv::Mat paint_coat(const BodyModel& body, int size, std::uint64_t seed,
                   const std::optional<Eigen::Vector3d>& key = std::nullopt);

}  // namespace fourd::synth::detail
