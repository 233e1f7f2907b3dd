#pragma once
// The synthetic performer: a skeleton, a skinned watertight mesh with UVs and a clothing
// texture, posed by forward kinematics and linear blend skinning.
#include <Eigen/Core>
#include <Eigen/Geometry>
#include <opencv2/core.hpp>
#include <cstdint>
#include <string>
#include <vector>

#include "pipeline/core/mesh.h"

namespace fourd::synth {

// Joints in topological order: parents[i] < i, parents[0] == -1 (the root, at the pelvis).
// At the rest pose every joint frame is axis-aligned with the world (standing at the origin,
// facing kForward, arms slightly lowered from a T-pose) and only offset from its parent.
struct Skeleton {
  std::vector<std::string> names;
  std::vector<int> parents;
  std::vector<Eigen::Vector3d> rest_offsets;  // joint position relative to its parent, metres
  std::size_t size() const { return names.size(); }
  int find(const std::string& name) const;  // -1 if absent
};

// World axes: z up, the floor is z = 0. At rest the character faces +x (kForward).
inline const Eigen::Vector3d kUp{0, 0, 1};
inline const Eigen::Vector3d kForward{1, 0, 0};

// One frame of animation.
struct Pose {
  Eigen::Vector3d root_position = Eigen::Vector3d::Zero();  // world position of joint 0
  std::vector<Eigen::Quaterniond> local_rotations;  // per joint, relative to the rest frame
};

// world_from_joint for every joint.
std::vector<Eigen::Isometry3d> forward_kinematics(const Skeleton& skeleton, const Pose& pose);

struct SkinnedMesh {
  Mesh rest;                                   // rest-pose mesh with per-vertex UVs
  std::vector<Eigen::Vector4i> joints;         // #V, up to 4 influencing joints
  std::vector<Eigen::Vector4f> weights;        // #V, summing to 1
  std::vector<Eigen::Isometry3d> inverse_bind;  // per joint: joint_from_world at rest
};

// Linear blend skinning: the rest mesh posed by world_from_joint. Keeps topology and UVs.
Mesh skin_mesh(const SkinnedMesh& skinned, const std::vector<Eigen::Isometry3d>& world_from_joint);

struct Character {
  std::string name;
  Skeleton skeleton;
  SkinnedMesh skin;
  cv::Mat texture;  // CV_8UC3 (BGR, OpenCV order), the clothing/skin albedo addressed by UVs
  double height = 0;  // rest-pose height, metres
};

}  // namespace fourd::synth
