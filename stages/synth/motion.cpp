#include "stages/synth/motion.h"

#include <fmt/format.h>

#include <Eigen/Geometry>
#include <cmath>

#include "pipeline/core/error.h"
#include "stages/synth/motion_generators.h"

namespace fourd::synth {
namespace {

// Speed, heading rate and cycle length of a cyclic motion, measured on its root over whole
// gait cycles (the pelvis sways about the root with the period of the cycle).
void measure_cyclic(MotionClip& clip) {
  if (!clip.amplitude.empty()) {
    // Pauses: the walking bouts' speed and turn rate, over the steps at full pace.
    double path = 0, turn = 0, seconds = 0;
    for (std::size_t f = 0; f + 1 < clip.root.size(); ++f) {
      if (clip.amplitude[f] < 1 || clip.amplitude[f + 1] < 1) continue;
      path += (clip.root[f + 1].position - clip.root[f].position).norm();
      turn += clip.root[f + 1].heading - clip.root[f].heading;
      seconds += 1 / clip.fps;
    }
    if (!(seconds > 0)) {
      throw ConfigError(fmt::format("take {}: its pauses leave no two frames in a row at full pace", clip.spec.take));
    }
    clip.parameters = {{"speed", path / seconds},
                       {"direction_deg_per_s", turn * 180 / M_PI / seconds},
                       {"cycle_s", clip.cycle_frames / clip.fps}};
    return;
  }
  const int frames = static_cast<int>(clip.root.size());
  const int cycle = static_cast<int>(std::lround(clip.cycle_frames));
  const int whole = cycle > 0 ? (frames - 1) / cycle * cycle : 0;
  const int span = whole > 0 ? whole : frames - 1;
  double path = 0;
  for (int f = 0; f < span; ++f) path += (clip.root[f + 1].position - clip.root[f].position).norm();
  const double seconds = span / clip.fps;
  const double turn = clip.root[span].heading - clip.root[0].heading;
  clip.parameters = {{"speed", path / seconds},
                     {"direction_deg_per_s", turn * 180 / M_PI / seconds},
                     {"cycle_s", clip.cycle_frames / clip.fps}};
}

// Jump length between the feet's stances at the first and last frames, apex height of the
// pelvis over its standing height at frame 0.
void measure_jump(const Skeleton& skeleton, MotionClip& clip) {
  const int foot_l = skeleton.find("foot_l"), foot_r = skeleton.find("foot_r");
  auto feet = [&](const Pose& pose) {
    const auto world = forward_kinematics(skeleton, pose);
    return Eigen::Vector2d(0.5 * (world[static_cast<std::size_t>(foot_l)].translation() +
                                  world[static_cast<std::size_t>(foot_r)].translation()).head<2>());
  };
  double top = clip.poses.front().root_position.z();
  for (const Pose& pose : clip.poses) top = std::max(top, pose.root_position.z());
  clip.parameters = {{"jump_length", (feet(clip.poses.back()) - feet(clip.poses.front())).norm()},
                     {"jump_height", top - clip.poses.front().root_position.z()}};
}

bool is_quadruped_kind(const std::string& kind) { return kind == "trot" || kind == "gallop"; }

}  // namespace

void MotionSpec::check() const {
  const bool cyclic = kind == "walk" || kind == "run" || kind == "turn";
  if (!cyclic && kind != "jump" && kind != "reach" && kind != "dance" && !is_quadruped_kind(kind)) {
    throw ConfigError(fmt::format("take {}: kind '{}' is not one of walk, run, turn, jump, reach, dance (a human's) "
                                  "or walk, trot, gallop (a quadruped's)", take, kind));
  }
  if (reach_target.size() != 3) {
    throw ConfigError(fmt::format("take {}: reach_target needs 3 values (x, y, z), not {}", take, reach_target.size()));
  }
  if (start_position.size() != 2) {
    throw ConfigError(fmt::format("take {}: start_position needs 2 values (x, y), not {}", take, start_position.size()));
  }
  if ((kind == "walk" || kind == "turn") && (speed < 0.3 || speed > 2.5)) {
    throw ConfigError(fmt::format("take {}: a {} needs a speed in [0.3, 2.5] m/s, not {}", take, kind, speed));
  }
  if (kind == "run" && (speed < 1.5 || speed > 6)) {
    throw ConfigError(fmt::format("take {}: a run needs a speed in [1.5, 6] m/s, not {}", take, speed));
  }
  if (kind == "jump" && (jump_height < 0.05 || jump_length > 3)) {
    throw ConfigError(fmt::format("take {}: a jump needs jump_height >= 0.05 m and jump_length <= 3 m "
                                  "(got {} and {})", take, jump_height, jump_length));
  }
  if (frames < 2) throw ConfigError(fmt::format("take {}: frames must be at least 2, not {}", take, frames));
  if (!pauses.empty() && kind != "walk" && kind != "turn") {
    throw ConfigError(fmt::format("take {}: only a walk or a turn can pause, not a {}", take, kind));
  }
  for (std::size_t i = 0; i < pauses.size(); ++i) {
    if (pauses[i].at + pauses[i].frames > frames) {
      throw ConfigError(fmt::format("take {}: pause {} (frames {} to {}) ends after the take's {} frames", take, i,
                                    pauses[i].at, pauses[i].at + pauses[i].frames - 1, frames));
    }
    if (i > 0 && pauses[i].at < pauses[i - 1].at + pauses[i - 1].frames) {
      throw ConfigError(fmt::format("take {}: pause {} starts at frame {}, before pause {} ends", take, i,
                                    pauses[i].at, i - 1));
    }
  }
}

MotionClip generate_motion(const Skeleton& skeleton, const MotionSpec& spec, double fps) {
  spec.check();
  if (!(fps > 0)) throw ConfigError(fmt::format("take {}: fps must be positive, not {}", spec.take, fps));
  if (is_quadruped(skeleton)) {
    if (spec.kind != "walk" && !is_quadruped_kind(spec.kind)) {
      throw ConfigError(fmt::format("take {}: a quadruped (character.body quadruped) performs walk, trot or gallop, "
                                    "not '{}'", spec.take, spec.kind));
    }
    MotionClip clip = detail::generate_quadruped_gait(skeleton, spec, fps);
    measure_cyclic(clip);
    return clip;
  }
  if (is_quadruped_kind(spec.kind)) {
    throw ConfigError(fmt::format("take {}: '{}' is a quadruped's gait (character.body quadruped); the human "
                                  "performer performs walk, run, turn, jump, reach or dance", spec.take, spec.kind));
  }
  const detail::Rig rig(skeleton);
  if (spec.kind == "jump") {
    MotionClip clip = detail::generate_jump(rig, spec, fps);
    measure_jump(skeleton, clip);
    return clip;
  }
  if (spec.kind == "reach") return detail::generate_reach(rig, spec, fps);
  if (spec.kind == "dance") return detail::generate_dance(rig, spec, fps);
  MotionClip clip = detail::generate_gait(rig, spec, fps);
  measure_cyclic(clip);
  return clip;
}

Eigen::Vector3d right_palm_position(const Skeleton& skeleton, const std::vector<Eigen::Isometry3d>& world_from_joint) {
  const int hand = skeleton.find("hand_r");
  if (hand < 0) throw InputError("right palm: the skeleton has no joint 'hand_r'");
  const Eigen::Vector3d along = skeleton.rest_offsets[static_cast<std::size_t>(hand)];  // forearm -> wrist at rest
  return world_from_joint[static_cast<std::size_t>(hand)] * (0.33 * along);
}

namespace detail {

void require_frames(const MotionSpec& spec, double seconds, double fps) {
  const int needed = static_cast<int>(std::ceil(seconds * fps)) + 1;
  if (spec.frames < needed) {
    throw ConfigError(fmt::format("take {}: a {} with these parameters lasts {:.2f} s and needs at least {} frames "
                                  "at {} fps (frames = {})", spec.take, spec.kind, seconds, needed, fps, spec.frames));
  }
}

MotionClip sample_one_shot(const Rig& rig, const MotionSpec& spec, double fps,
                           const std::function<RootState(double)>& root,
                           const std::function<WorldPose(double)>& pose) {
  MotionClip clip;
  clip.spec = spec;
  clip.fps = fps;
  for (int f = 0; f < spec.frames; ++f) {
    const double t = f / fps;
    clip.root.push_back(root(t));
    clip.phase.push_back(static_cast<double>(f) / spec.frames);
    clip.poses.push_back(pose(t).to_pose(rig.skeleton));
  }
  return clip;
}

MotionClip sample_cyclic(const Skeleton& skeleton, const MotionSpec& spec, double fps, double cycle_frames,
                         const std::function<RootState(double)>& root, const std::function<double(double)>& phase,
                         const std::function<WorldPose(double)>& pose) {
  MotionClip clip;
  clip.spec = spec;
  clip.fps = fps;
  clip.cycle_frames = cycle_frames;
  for (int f = 0; f < spec.frames; ++f) {
    const double t = f / fps;
    clip.root.push_back(root(t));
    const double phi = phase(t);
    clip.phase.push_back(phi - std::floor(phi));
    clip.poses.push_back(pose(t).to_pose(skeleton));
  }
  return clip;
}

RootState start_state(const MotionSpec& spec) {
  RootState r;
  r.position = Eigen::Vector2d(spec.start_position[0], spec.start_position[1]);
  r.heading = spec.start_heading * M_PI / 180;
  return r;
}

}  // namespace detail
}  // namespace fourd::synth
