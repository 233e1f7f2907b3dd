#pragma once
// BVH (Biovision hierarchy) motion capture: reading any Euler channel order, writing, and
// retargeting a BVH take onto our skeleton, so users can drive the synthetic performer with
// their own motion capture.
//
// Axes: BVH files are usually y-up with the performer facing +z; with `y_up` the reader and
// writer convert with the same fixed rotation as glTF (BVH +z -> our +x, +x -> +y, +y -> +z).
// BVH joint frames at rest are aligned with the file's axes, like ours, so the conversion is
// exact: offsets and positions are rotated, local rotations conjugated.
#include <filesystem>
#include <map>
#include <string>
#include <utility>
#include <vector>

#include "pipeline/core/config.h"
#include "stages/synth/character.h"

namespace fourd::synth {

struct BvhOptions {
  double metres_per_unit = 0.01;  // length unit of the file [m]; BVH is most often centimetres
  bool y_up = true;               // the file is y-up facing +z (else already z-up facing +x)

  template <class V>
  void visit(V& v) {
    v("metres_per_unit", metres_per_unit, "length unit of the BVH file [m]", Range{1e-6, 1e3});
    v("y_up", y_up, "BVH is y-up facing +z (else z-up facing +x)");
  }
};

struct BvhMotion {
  std::string source;  // the file it was read from, for messages
  Skeleton skeleton;   // joints in file order (parent first), our axes, metres
  std::vector<Pose> frames;
  double frame_time = 0;  // seconds per frame
  // Per joint, its channel names as in the file, e.g. {"Xposition", ..., "Zrotation", ...}.
  std::vector<std::vector<std::string>> channels;
  // The "End Site" of leaf joints: (joint, offset from it, our axes, metres).
  std::vector<std::pair<int, Eigen::Vector3d>> end_sites;
  double fps() const { return frame_time > 0 ? 1 / frame_time : 0; }
};

// Reads a BVH file. Position channels on the root give its position (they replace its OFFSET,
// as most tools read them); position channels on other joints are not represented by our
// skeleton and are ignored (their OFFSET is used). Throws IoError if the file cannot be read,
// InputError naming the file and line for a malformed file.
BvhMotion read_bvh(const std::filesystem::path& path, const BvhOptions& options = {});

// Writes `path` atomically: the skeleton's hierarchy (the root with Xposition Yposition
// Zposition Zrotation Xrotation Yrotation channels, every other joint Zrotation Xrotation
// Yrotation; leaves end in a zero End Site) and one line per pose at `fps`.
// Throws InputError if a pose does not match the skeleton, IoError if the file cannot be written.
void write_bvh(const std::filesystem::path& path, const Skeleton& skeleton,
               const std::vector<Pose>& poses, double fps, const BvhOptions& options = {});

// BVH joint name -> our joint name for common motion capture skeletons (CMU, Mixamo, Poser,
// MotionBuilder), onto the joints of the procedural character.
std::map<std::string, std::string> default_bvh_joint_map();

// Retargets `motion` onto `target`. `joint_map` maps source joint names to target joint names;
// entries whose joints do not exist in either skeleton are skipped (so one map serves several
// naming schemes; a source name also matches after a "namespace:" prefix), and when several
// present source joints map to one target joint the deepest in the source hierarchy wins.
//
// Rotations are transferred in world space: each mapped target joint takes the world rotation
// of its source joint times a fixed rest alignment that turns the target's rest bones onto the
// source's rest bones (so a T-pose source and an A-pose target still agree on where the arms
// point). Unmapped target joints keep their rest orientation relative to their parent. The
// root's position is the position of the source joint mapped to the target root, scaled by the
// ratio of the two skeletons' leg lengths (root height above the lowest mapped joint at rest).
// Throws InputError (naming the source file) if the target root is not mapped or no joint is.
std::vector<Pose> retarget_bvh(
    const BvhMotion& motion, const Skeleton& target,
    const std::map<std::string, std::string>& joint_map = default_bvh_joint_map());

}  // namespace fourd::synth
