#pragma once
// Procedural motions with exactly known parameters. Root motion (the performer travels and
// turns on the ground plane) is part of the motion.
#include <Eigen/Core>
#include <string>
#include <vector>

#include "pipeline/core/config.h"
#include "stages/synth/character.h"

namespace fourd::synth {

// A stand in a walk or a turn: the performer slows to a stop over one gait cycle, stands still
// (feet planted, weight swaying a little) for `frames` frames from frame `at`, and sets off
// again over one gait cycle.
struct PauseSpec {
  int at = 0;      // first frame standing still
  int frames = 1;  // frames standing still

  template <class V>
  void visit(V& v) {
    v("at", at, "first frame of the stand", Range{0, 100000});
    v("frames", frames, "frames standing still", Range{1, 100000});
  }
};

// One take of the synthetic database. Only the fields of its kind are used.
struct MotionSpec {
  std::string take;       // take name, e.g. "walk_slow"
  // walk | run | turn | jump | reach | dance (the human performer); walk | trot | gallop (the
  // quadruped, character.body quadruped)
  std::string kind;
  int frames = 30;        // number of frames to generate
  double speed = 1.2;     // walk/run/turn/trot/gallop: ground speed [m/s]
  // turn: heading change [deg/s], + = left (counter-clockwise from above); dance: the spin's
  // heading change over the whole take, per second of the take
  double turn_rate = 0;
  double jump_length = 0;  // jump: horizontal distance take-off to landing [m]
  double jump_height = 0;  // jump: apex clearance of the pelvis above standing height [m]
  // reach: right-hand target in the body frame at frame 0 (x forward, y left, z up) [m]
  std::vector<double> reach_target = {0.5, -0.2, 1.0};
  double start_heading = 0;  // heading of kForward at frame 0 [deg], about +z
  std::vector<double> start_position = {0, 0};  // root ground position at frame 0 [m]
  double start_phase = 0;    // cyclic motions: gait phase at frame 0 in [0,1)
  // walk, turn: stands between walking bouts, in order, a stand's slowing and setting off
  // (one gait cycle each) apart from the next's
  std::vector<PauseSpec> pauses;

  template <class V>
  void visit(V& v) {
    v("take", take, "take name (folder under capture/)");
    v("kind", kind, "walk | run | turn | jump | reach | dance; a quadruped's: walk | trot | gallop");
    v("frames", frames, "number of frames", Range{2, 100000});
    v("speed", speed, "walk/run/turn/trot/gallop ground speed [m/s]", Range{0, 20});
    v("turn_rate", turn_rate,
      "turn: heading change [deg/s], + = left; dance: the spin's, over the whole take",
      Range{-360, 360});
    v("jump_length", jump_length, "jump: take-off to landing distance [m]", Range{0, 5});
    v("jump_height", jump_height, "jump: apex rise of the pelvis [m]", Range{0, 2});
    v("reach_target", reach_target, "reach: hand target in the body frame (x fwd, y left, z up) [m]");
    v("start_heading", start_heading, "heading at frame 0 [deg]", Range{-360, 360});
    v("start_position", start_position, "ground position at frame 0 [m]");
    v("start_phase", start_phase, "gait phase at frame 0", Range{0, 1});
    v("pauses", pauses, "walk, turn: stands [{at: first frame, frames: how many}], slowing and setting off "
      "over a gait cycle each");
  }
  void check() const;  // kind known, vectors of the right length
};

// The root's ground-plane state per frame: the path the performer follows (for walk, run and
// turn the straight line or arc travelled at exactly the spec's speed, without the pelvis's
// periodic sway, which averages out over a gait cycle; for jump and reach the pelvis's ground
// position) and the facing direction (heading, continuous: never wrapped).
struct RootState {
  Eigen::Vector2d position;  // world x, y [m]
  double heading = 0;        // [rad], angle of the facing direction from +x about +z
};

struct MotionClip {
  MotionSpec spec;
  double fps = 25;
  std::vector<Pose> poses;          // #frames
  std::vector<RootState> root;      // #frames
  std::vector<double> phase;        // #frames, in [0,1): gait cycle phase, or normalised time
                                    // for one-shot motions (jump, reach, dance)
  double cycle_frames = 0;          // cyclic motions: frames per gait cycle (0 otherwise)
  // A walk or turn with pauses: per frame, how far the gait is under way (1 walking, 0
  // standing still, between them slowing down or setting off); empty without pauses.
  std::vector<double> amplitude;
  // Parameters measured on the generated motion itself (ground truth for validation), e.g.
  // {"speed": 1.21, "direction_deg_per_s": 0} or {"jump_length": 1.2, "jump_height": 0.3}.
  //   walk, run, turn, trot, gallop: speed [m/s] (root path length over whole gait cycles / their
  //     duration), direction_deg_per_s (heading change over whole cycles / duration),
  //     cycle_s (gait cycle duration); with pauses, speed and direction over the frames at full
  //     pace only
  //   jump: jump_length [m] (horizontal distance between the feet's stances before and after),
  //     jump_height [m] (highest pelvis height minus the standing pelvis height at frame 0)
  //   reach: reach_x, reach_y, reach_z [m] (right palm centre while holding at the target, in
  //     the body frame of frame 0: x forward, y left from the root, z above the floor)
  //   dance: direction_deg_per_s (heading change first to last frame / duration), spin_deg
  //     (the spin's heading change), spin_peak_deg_per_s (its highest rate)
  std::vector<std::pair<std::string, double>> parameters;
};

// The motion of `spec` for the procedural performer's skeleton (joint names of
// make_procedural_character): the human's kinds for the human, walk, trot and gallop for the
// quadruped. Deterministic. Throws ConfigError for a spec that cannot be performed (unknown
// kind, a kind of the other body, too few frames for a one-shot motion, an unreachable target,
// a gait's speed out of its range).
MotionClip generate_motion(const Skeleton& skeleton, const MotionSpec& spec, double fps);

// Centre of the right palm (the point that reach motions bring to reach_target) for a pose's
// world_from_joint: on the hand's axis, a third of the forearm's length beyond the wrist.
Eigen::Vector3d right_palm_position(const Skeleton& skeleton,
                                    const std::vector<Eigen::Isometry3d>& world_from_joint);

}  // namespace fourd::synth
