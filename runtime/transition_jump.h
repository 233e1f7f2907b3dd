#pragma once
// How smooth a played transition is: the largest per-frame displacement of any vertex (world
// coordinates, root applied) while the transition plays, against the motions' own speeds, the
// 99th percentile of every vertex's per-frame displacement over one pass of each motion at
// its parameter. A ratio above 1 is a vertex moving faster than the captured motions do
// (a lurch); the cross-fade is sized to keep it near 1 (runtime/character.h).
#include <vector>

#include "runtime/character.h"

namespace fourd {

// The 99th percentile of the per-frame displacement of every vertex of `space` played at
// parameter p over one pass (a cyclic space: one cycle; a one-shot: t from 0 to 1), frames
// `frame_seconds` apart [m]. Allocates.
double motion_displacement_p99(const MotionGraph& graph, int space, double p,
                               double frame_seconds);

// Largest vertex displacement between consecutive frames fed to it (world coordinates).
class VertexJumpMeter {
 public:
  // The largest displacement from the previous frame's world positions [m] (0 for the first).
  double add(const CharacterFrame& frame);
  void clear() { previous_.clear(); }

 private:
  std::vector<Vec3f> previous_, current_;
};

// Which frames a transition's jump is measured on: from the frame that crosses the switch to
// the last frame of the cross-fade. Before the switch the source plays as captured, and its
// own fastest frames (a dance's arm swing at twice its 99th percentile) are no lurch.
class CrossFadeWindow {
 public:
  // Whether the frame just stepped, after which the character's last transition is `r` and its
  // state `s`, is in the window. Call once per frame, in order.
  bool counts(const TransitionRecord& r, const CharacterState& s);

 private:
  double counted_switch_ = -1;  // switch_time of the last switch whose frame was counted
  bool was_fading_ = false;
};

struct TransitionJump {
  bool played = false;       // the transition switched and arrived within the time allowed
  double worst_m = 0;        // largest per-frame vertex displacement in its CrossFadeWindow [m]
  double source_p99_m = 0;   // motion_displacement_p99 of the source at the request's parameter
  double target_p99_m = 0;   // and of the target at the requested parameter
  double ratio() const {
    const double ref = std::max(source_p99_m, target_p99_m);
    return ref > 0 ? worst_m / ref : 0.0;
  }
};

// Plays one request on `character` (reset to `from`, then request_motion(to)) at frames
// `frame_seconds` apart until the requested state is reached and the cross-fade is over, at
// most `max_seconds`, and measures the jump over the frames of its CrossFadeWindow.
TransitionJump measure_transition_jump(Character& character, const MotionState& from,
                                       const TransitionTarget& to, double frame_seconds,
                                       double max_seconds = 30);

}  // namespace fourd
