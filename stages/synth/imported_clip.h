#pragma once
// Turns a pose sequence that came from outside the studio (a glTF animation, a retargeted BVH
// take) into a MotionClip: root ground track, heading, normalised time and the parameters
// measured on the motion itself.
#include <string>
#include <vector>

#include "stages/synth/character.h"
#include "stages/synth/motion.h"

namespace fourd::synth {

// The MotionSpec kind of clips that were not generated procedurally.
inline constexpr const char* kImportedKind = "imported";

// `poses` must not be empty and `fps` must be positive. The clip's root track is the ground
// projection of the root joint, its heading the angle of the root's kForward axis about kUp
// (unwrapped, so it does not jump by 2 pi), its phase the normalised time i / n in [0,1), and its
// parameters the measured "speed" (net ground displacement / duration, m/s) and
// "direction_deg_per_s" (heading change / duration).
MotionClip make_imported_clip(const std::string& take, std::vector<Pose> poses, double fps);

}  // namespace fourd::synth
