#pragma once
// Procedural motions with exactly known parameters. Root motion (the performer travels and
// turns on the ground plane) is part of the motion.
#include <Eigen/Core>
#include <string>
#include <vector>

#include "pipeline/core/config.h"
#include "stages/synth/character.h"

namespace fourd::synth {

// One take of the synthetic database. Only the fields of its kind are used.
struct MotionSpec {
  std::string take;       // take name, e.g. "walk_slow"
  std::string kind;       // walk | run | turn | jump | reach
  int frames = 30;        // number of frames to generate
  double speed = 1.2;     // walk/run/turn: ground speed [m/s]
  double turn_rate = 0;   // turn: heading change [deg/s], + = left (counter-clockwise from above)
  double jump_length = 0;  // jump: horizontal distance take-off to landing [m]
  double jump_height = 0;  // jump: apex clearance of the pelvis above standing height [m]
  // reach: right-hand target in the body frame at frame 0 (x forward, y left, z up) [m]
  std::vector<double> reach_target = {0.5, -0.2, 1.0};
  double start_heading = 0;  // heading of kForward at frame 0 [deg], about +z
  std::vector<double> start_position = {0, 0};  // root ground position at frame 0 [m]
  double start_phase = 0;    // cyclic motions: gait phase at frame 0 in [0,1)

  template <class V>
  void visit(V& v) {
    v("take", take, "take name (folder under capture/)");
    v("kind", kind, "walk | run | turn | jump | reach");
    v("frames", frames, "number of frames", Range{2, 100000});
    v("speed", speed, "walk/run/turn ground speed [m/s]", Range{0, 10});
    v("turn_rate", turn_rate, "turn: heading change [deg/s], + = left", Range{-360, 360});
    v("jump_length", jump_length, "jump: take-off to landing distance [m]", Range{0, 5});
    v("jump_height", jump_height, "jump: apex rise of the pelvis [m]", Range{0, 2});
    v("reach_target", reach_target, "reach: hand target in the body frame (x fwd, y left, z up) [m]");
    v("start_heading", start_heading, "heading at frame 0 [deg]", Range{-360, 360});
    v("start_position", start_position, "ground position at frame 0 [m]");
    v("start_phase", start_phase, "gait phase at frame 0", Range{0, 1});
  }
  void check() const;  // kind known, vectors of the right length
};

// The root's ground-plane state per frame.
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
                                    // for one-shot motions (jump, reach)
  double cycle_frames = 0;          // cyclic motions: frames per gait cycle (0 otherwise)
  // Parameters measured on the generated motion itself (ground truth for validation), e.g.
  // {"speed": 1.21, "direction_deg_per_s": 0} or {"jump_length": 1.2, "jump_height": 0.3}.
  std::vector<std::pair<std::string, double>> parameters;
};

MotionClip generate_motion(const Skeleton& skeleton, const MotionSpec& spec, double fps);

}  // namespace fourd::synth
