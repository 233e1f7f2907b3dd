#pragma once
// The synthetic performer: a skeleton, a skinned watertight mesh with UVs and a clothing
// texture, posed by forward kinematics and linear blend skinning.
#include <Eigen/Core>
#include <Eigen/Geometry>
#include <opencv2/core.hpp>
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "pipeline/core/config.h"
#include "pipeline/core/mesh.h"

namespace fourd::synth {

// Joints in topological order: parents[i] < i, parents[0] == -1 (the root, at the pelvis).
// At the rest pose every joint frame is axis-aligned with the world (standing at the origin,
// facing kForward, arms lowered 45 degrees from a T-pose) and only offset from its parent.
// rest_offsets[0] is the root's rest position in the world.
//
// The procedural performer has 21 joints: pelvis, spine, chest, neck, head,
// clavicle_{l,r}, upper_arm_{l,r}, forearm_{l,r}, hand_{l,r}, thigh_{l,r}, shin_{l,r},
// foot_{l,r} (at the ankle), toe_{l,r} (at the ball of the foot). The procedural quadruped
// (quadruped.h) has 24: pelvis, spine, chest, neck, head, tail_{0,1,2}, upper_arm_{l,r},
// forearm_{l,r}, front_cannon_{l,r}, front_hoof_{l,r}, thigh_{l,r}, shin_{l,r},
// hind_cannon_{l,r}, hind_hoof_{l,r}; it stands on four hooves facing kForward.
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

// Whether the skeleton is the procedural quadruped's (it has hooves).
bool is_quadruped(const Skeleton& skeleton);

// The rest pose: root at rest_offsets[0], every local rotation the identity.
Pose rest_pose(const Skeleton& skeleton);

// world_from_joint for every joint. Throws InputError if the pose has the wrong joint count.
std::vector<Eigen::Isometry3d> forward_kinematics(const Skeleton& skeleton, const Pose& pose);

struct SkinnedMesh {
  // Rest-pose mesh with per-vertex UVs; uv (0,0) is the bottom-left corner of the texture
  // image, (1,1) the top-right (the OBJ convention: image row = (1 - v) * rows).
  Mesh rest;
  std::vector<Eigen::Vector4i> joints;         // #V, up to 4 influencing joints
  std::vector<Eigen::Vector4f> weights;        // #V, summing to 1
  std::vector<Eigen::Isometry3d> inverse_bind;  // per joint: joint_from_world at rest
};

// Linear blend skinning: the rest mesh posed by world_from_joint. Keeps topology and UVs.
Mesh skin_mesh(const SkinnedMesh& skinned, const std::vector<Eigen::Isometry3d>& world_from_joint);

struct Garment;  // garment.h

struct Character {
  std::string name;
  Skeleton skeleton;
  SkinnedMesh skin;
  cv::Mat texture;  // CV_8UC3 (BGR, OpenCV order), the clothing/skin albedo addressed by UVs
  double height = 0;  // rest-pose height, metres
  // A loose garment over the skin (a skirt), moved by cloth simulation rather than skinning
  // (garment.h: PerformerSurface poses both); null when the character wears none.
  std::shared_ptr<const Garment> garment;
};

// The procedural performer. Shape from these values; clothing colours and patterns from the
// seed. Same values and seed give bit-identical meshes, weights and texture.
struct CharacterOptions {
  std::string name = "performer";
  // "human", or "quadruped": a procedural hoofed animal (quadruped.h) that walks, trots and
  // gallops (no garment).
  std::string body = "human";
  // Standing height, floor to the top of the head [m]: the human's 1.2 to 2.2 m, the
  // quadruped's (to the tips of its ears, its highest point; its withers are at 0.75 of it)
  // 0.3 to 2.2 m.
  double height = 1.75;
  double build = 1.0;          // girth of torso and limbs relative to an average build
  int target_vertices = 5000;  // vertex count of the mesh (met within about 10 %)
  int texture_size = 1024;     // texture width and height [px]
  // Skinning: the width of the weights' blend between two bones, as a multiple of the body's
  // smooth-union radius (12 mm at 1.75 m); the same for the bones where the limbs join the trunk
  // (pelvis, spine, chest, clavicles, upper arms, thighs); rounds of averaging the weights over
  // the mesh's neighbours. Narrow blends stretch the skin inside a bending joint many times
  // over: with trunk_skin_blend 1.2 (as narrow as elsewhere) an armpit's skin stretches 7.8x as
  // the arm rises overhead; at the default 3, 2.8x. Wide blends everywhere (skin_blend 3,
  // skin_smoothing 20: 2.6x) also bend a foot's sole, which then no longer stays flat on the
  // floor through a stance.
  double skin_blend = 1.2;
  double trunk_skin_blend = 3;
  int skin_smoothing = 4;
  // A loose garment over the body: "none", or "skirt", a flared skirt sewn to the waist whose
  // cloth is simulated from the body's motion (garment.h). The skirt's length runs from the
  // waist to the hem along the cloth, as a fraction of the waist's height above the floor
  // (0.45: the hem a little above the knee); its flare is the half-angle of the cone it is cut
  // as, how far out it can swing (90 would be a circle skirt). Length and flare are tuned
  // values (docs/synth.md, "Advanced").
  std::string garment = "none";
  double skirt_length = 0.45;
  double skirt_flare = 40;

  // The options: another body (#46's second body shape) and its clothing. The rest are tuned
  // values of the procedural performer.
  template <class V>
  void visit(V& v) {
    v("body", body, "human | quadruped: a procedural hoofed animal that walks, trots and gallops");
    v("height", height, "standing height to the top of the head [m] (a quadruped's: its ears' tips)",
      Range{0.3, 2.2});
    v("build", build, "girth relative to an average build", Range{0.75, 1.35});
    v("garment", garment,
      "none | skirt: a loose garment over the body, its cloth simulated from the body's motion");
  }
  void check() const;  // a known body and garment, a height for the body

  // The keys of the garment's options: a session without a garment records none of them.
  static constexpr const char* kGarmentKeys[] = {"garment"};
  // The same for the body's: a human performer's session records none.
  static constexpr const char* kBodyKeys[] = {"body"};
};

// A watertight, manifold, outward-oriented body mesh meshed from an implicit body of
// smoothly blended ellipsoids and capsules around the bones, remeshed to near-uniform edges,
// with smooth skinning weights, per-vertex UVs and a clothing texture (shirt, trousers, skin,
// hair, shoes; never green, which is the backdrop's colour). With options.garment "skirt", also
// the skirt (character.garment), hanging still on the rest pose, its colours in the texture.
// `wardrobe_key`: the studio's key colour (studio_key_color), kept out of the clothes.
// With options.body "quadruped", the quadruped (quadruped.h): meshed, skinned and textured the
// same way, its coat in place of the clothes.
Character make_procedural_character(const CharacterOptions& options, std::uint64_t seed,
                                    const std::optional<Eigen::Vector3d>& wardrobe_key = {});

}  // namespace fourd::synth
