// Skeleton queries, forward kinematics and linear blend skinning.
#include <fmt/format.h>

#include "pipeline/core/error.h"
#include "stages/synth/character.h"

namespace fourd::synth {

int Skeleton::find(const std::string& name) const {
  for (std::size_t i = 0; i < names.size(); ++i) {
    if (names[i] == name) return static_cast<int>(i);
  }
  return -1;
}

bool is_quadruped(const Skeleton& skeleton) { return skeleton.find("front_hoof_l") >= 0; }

Pose rest_pose(const Skeleton& skeleton) {
  Pose pose;
  if (skeleton.size() > 0) pose.root_position = skeleton.rest_offsets[0];
  pose.local_rotations.assign(skeleton.size(), Eigen::Quaterniond::Identity());
  return pose;
}

std::vector<Eigen::Isometry3d> forward_kinematics(const Skeleton& skeleton, const Pose& pose) {
  const std::size_t n = skeleton.size();
  if (pose.local_rotations.size() != n) {
    throw InputError(fmt::format("forward kinematics: pose has {} joint rotations, skeleton {} joints",
                                 pose.local_rotations.size(), n));
  }
  std::vector<Eigen::Isometry3d> world(n);
  for (std::size_t i = 0; i < n; ++i) {
    Eigen::Isometry3d local = Eigen::Isometry3d::Identity();
    local.linear() = pose.local_rotations[i].normalized().toRotationMatrix();
    const int parent = skeleton.parents[i];
    if (parent < 0) {
      local.translation() = pose.root_position;
      world[i] = local;
    } else {
      local.translation() = skeleton.rest_offsets[i];
      world[i] = world[static_cast<std::size_t>(parent)] * local;
    }
  }
  return world;
}

Mesh skin_mesh(const SkinnedMesh& skinned, const std::vector<Eigen::Isometry3d>& world_from_joint) {
  const std::size_t joints = skinned.inverse_bind.size();
  if (world_from_joint.size() != joints) {
    throw InputError(fmt::format("skinning: {} joint transforms for a skin bound to {} joints",
                                 world_from_joint.size(), joints));
  }
  // One 3x4 matrix per joint takes a rest vertex to its pose under that joint alone.
  std::vector<Eigen::Matrix<float, 3, 4>> skinning(joints);
  for (std::size_t j = 0; j < joints; ++j) {
    skinning[j] = (world_from_joint[j] * skinned.inverse_bind[j]).matrix().topRows<3>().cast<float>();
  }
  Mesh out;
  out.triangles = skinned.rest.triangles;
  out.colors = skinned.rest.colors;
  out.uvs = skinned.rest.uvs;
  out.uv_triangles = skinned.rest.uv_triangles;
  out.texture = skinned.rest.texture;
  const std::size_t nv = skinned.rest.positions.size();
  if (skinned.weights.size() != nv || skinned.joints.size() != nv) {
    throw InputError(fmt::format("skinning: {} weights and {} joint sets for {} vertices", skinned.weights.size(),
                                 skinned.joints.size(), nv));
  }
  out.positions.resize(nv);
  const bool with_normals = skinned.rest.normals.size() == nv;
  if (with_normals) out.normals.resize(nv);
  for (std::size_t v = 0; v < nv; ++v) {
    Eigen::Matrix<float, 3, 4> blend = Eigen::Matrix<float, 3, 4>::Zero();
    for (int k = 0; k < 4; ++k) {
      const float w = skinned.weights[v][k];
      if (w != 0.0f) blend += w * skinning[static_cast<std::size_t>(skinned.joints[v][k])];
    }
    const Vec3f& p = skinned.rest.positions[v];
    out.positions[v] = blend.leftCols<3>() * p + blend.col(3);
    if (with_normals) {
      // The blended linear part is close to a rotation; its inverse transpose would be exact
      // but the difference is invisible for smooth weights.
      out.normals[v] = (blend.leftCols<3>() * skinned.rest.normals[v]).normalized();
    }
  }
  return out;
}

}  // namespace fourd::synth
