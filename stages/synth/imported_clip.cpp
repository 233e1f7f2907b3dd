#include "stages/synth/imported_clip.h"

#include <cmath>
#include <numbers>

namespace fourd::synth {

MotionClip make_imported_clip(const std::string& take, std::vector<Pose> poses, double fps) {
  MotionClip clip;
  const int n = static_cast<int>(poses.size());
  clip.spec.take = take;
  clip.spec.kind = kImportedKind;
  clip.spec.frames = n;
  clip.fps = fps;
  clip.poses = std::move(poses);
  clip.root.resize(n);
  clip.phase.resize(n);
  double previous_heading = 0;
  for (int i = 0; i < n; ++i) {
    const Pose& pose = clip.poses[i];
    RootState& root = clip.root[i];
    root.position = pose.root_position.head<2>();
    Eigen::Vector3d forward = kForward;
    if (!pose.local_rotations.empty()) forward = pose.local_rotations[0] * kForward;
    double heading = std::atan2(forward.y(), forward.x());
    // Unwrap: a turning take accumulates heading past +-pi without a jump.
    if (i > 0) {
      heading +=
          2 * std::numbers::pi * std::round((previous_heading - heading) / (2 * std::numbers::pi));
    }
    root.heading = heading;
    previous_heading = heading;
    clip.phase[i] = static_cast<double>(i) / n;
  }
  if (n > 1) {
    const double duration = (n - 1) / fps;
    const double distance = (clip.root.back().position - clip.root.front().position).norm();
    const double turn = clip.root.back().heading - clip.root.front().heading;
    clip.parameters = {{"speed", distance / duration},
                       {"direction_deg_per_s", turn * 180 / std::numbers::pi / duration}};
  }
  return clip;
}

}  // namespace fourd::synth
