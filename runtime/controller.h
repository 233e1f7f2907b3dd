#pragma once
// High-level control of a runtime Character (runtime/character.h): walk or run at a speed and
// heading, jump with a length, and follow a path of contiguous cubic Bezier curves on the
// ground (the paper's Figure 8c).
//
// The controller runs inside the character's tick (Character::TickHook), so its decisions are
// taken at the same motion times whatever the frame rate.
//
// Motions are found by name: options.locomotion_space (cyclic, parameter = speed [m/s]),
// options.jump_space (one-shot, parameter = length [m]), options.turning_space (cyclic,
// parameter = turn rate [deg/s]) and options.reach_space (one-shot, parameter = the hand's
// height at the furthest point of the reach [m]); what the asset lacks is reported by has_*()
// and the matching commands refuse (a path is followed without turning by rotating the root).
//
// Steering. Path following is pure pursuit: the root aims at the path point `lookahead` metres
// ahead of its closest point, with a turn rate proportional to the heading error plus a term on
// the lateral offset, applied by rotating the root (Character::set_turn_rate) on top of the
// motion's own root curve. With a turning space, a curve that needs at least turn_enter_rate
// (the path's curvature over `turn_preview` metres ahead times the speed) is walked in the
// turning space at that rate, so the body turns by itself and the root rotation only corrects
// what is left; below turn_exit_rate the character goes back to locomotion at the curve's speed.
// Without a turning space the root rotation does all the turning (honest for gentle curves, it
// looks like sliding on tight ones). follow_status() reports how much of the turning was root
// rotation.
//
// Placing a one-shot motion. A jump over a gap (a curve marked as a gap: its chord is the jump
// length; the jump's middle, its root at t = 0.5, goes to the gap's middle) and a reach (the
// hand at the furthest point of the reach goes to the target) must happen at a given place. A
// transition plays the source on to its best exit first, so the controller predicts where the
// motion's key point would be if requested now: it runs the same online search the character
// will run (allocation-free) and adds the source's root travel to the exit and the motion's own
// root travel from its entry to the key point. The search exits at a favoured phase of the
// cycle, so the prediction is a staircase that steps by a fraction of one cycle's travel.
// Requesting on the step nearest to the goal leaves an error of up to half a step; so while the
// goal is k >= 1 steps ahead, the controller sets the locomotion speed whose cycle travel puts
// the k-th step on the goal, and requests on the step that reaches it. The step is measured as the
// prediction runs (half a cycle at first: a walk offers a take-off from either foot).
#include <array>
#include <string>
#include <vector>

#include "runtime/character.h"

namespace fourd {

struct Point2 {
  double x = 0, y = 0;
};

// One cubic Bezier curve on the ground; consecutive curves share end points.
struct BezierCurve {
  std::array<Point2, 4> control;
  double speed = -1;  // [m/s] locomotion speed on this curve (< 0: keep the previous)
  bool gap = false;   // jump over this curve (its chord length is the jump length)
};

// A path of contiguous curves with an arc-length table (built once; queries allocate nothing).
class GroundPath {
 public:
  GroundPath() = default;
  // Throws InputError when there are no curves, a curve does not start where the previous one
  // ends (1 mm tolerance), or a point is not finite.
  explicit GroundPath(std::vector<BezierCurve> curves, double sample_spacing = 0.005);

  double length() const { return length_; }
  const std::vector<BezierCurve>& curves() const { return curves_; }
  Point2 point_at(double s) const;
  double heading_at(double s) const;  // tangent direction [rad]
  int curve_at(double s) const;
  double curve_start(int curve) const { return curve_start_[curve]; }
  double curve_end(int curve) const { return curve_start_[curve + 1]; }
  // Arc length of the point of the path nearest to p, searched within [s_from, s_to].
  double closest(const Point2& p, double s_from, double s_to) const;

 private:
  std::vector<BezierCurve> curves_;
  std::vector<double> s_;  // arc length at each sample
  std::vector<Point2> points_;
  std::vector<int> curve_of_;  // curve of each sample
  std::vector<double> curve_start_;
  double length_ = 0;
};

struct ControllerOptions {
  std::string locomotion_space = "locomotion";
  std::string jump_space = "jump_length";
  std::string turning_space = "turning";
  std::string reach_space = "reach";
  double lookahead = 0.6;        // [m] pure-pursuit look-ahead distance
  double heading_gain = 3.0;     // [1/s] turn rate per radian of heading error
  double lateral_gain = 1.5;     // [rad/s per m] turn rate per metre of lateral offset
  double jump_search_distance = 6.0;  // [m] start predicting the jump this far before a gap
  double arrive_distance = 0.05; // [m] the path is done when this close to its end
  double turn_enter_rate = 12;   // [deg/s] a curve needing this much is walked in the turning space
  double turn_exit_rate = 6;     // [deg/s] below this, back to locomotion
  double turn_preview = 1.0;     // [m] path length over which the curvature ahead is averaged
  void check() const;            // throws ConfigError naming the field
};

// What the follower measured (for the player's log and the tests).
struct FollowStatus {
  bool active = false;
  bool done = false;
  double s = 0;              // arc length of the root's closest path point [m]
  double s_start = 0;        // s when the follow started [m]
  double lateral_error = 0;  // [m] signed distance of the root from the path (left positive)
  double max_abs_error = 0;  // [m] over the whole follow so far (jumps included)
  double travelled = 0;      // [m] root distance travelled since follow()
  int jumps = 0;
  double predicted_jump_middle = -1;  // [m] arc length where the last requested jump peaks
  // Where the jumps happened: arc length of the root at the jump's t = 0.5 minus the gap's
  // middle [m], the last one and the largest in magnitude.
  double jump_offset = 0;
  double max_abs_jump_offset = 0;
  int turning_requests = 0;  // requests into the turning space
  double total_turn = 0;     // [rad] |heading change| of the root while following
  double root_turn = 0;      // [rad] of it made by rotating the root (set_turn_rate)
};

// A reach (Controller::reach) and how close the hand came.
struct ReachStatus {
  bool active = false;           // approaching the target, or reaching
  bool requested = false;        // the reach motion was requested
  bool done = false;             // the hand passed its furthest point
  double target[3] = {0, 0, 0};  // world [m]
  double parameter = 0;          // the reach space's parameter used (the target's height, clamped)
  int hand_vertex = -1;          // the vertex that moves most in the reach (the hand)
  double apex_t = 0;             // normalised time of the hand's furthest point
  double hand[3] = {0, 0, 0};    // world position of the hand at apex_t [m] (when done)
  double hand_error = -1;        // [m] distance of the hand from the target at apex_t (when done)
};

class Controller : public Character::TickHook {
 public:
  // Installs itself as the character's tick hook (and removes itself when destroyed).
  Controller(Character& character, const ControllerOptions& options = {});
  ~Controller() override;
  Controller(const Controller&) = delete;
  Controller& operator=(const Controller&) = delete;

  bool has_locomotion() const { return locomotion_ >= 0; }
  bool has_jump() const { return jump_ >= 0; }
  bool has_turning() const { return turning_ >= 0; }
  bool has_reach() const { return reach_ >= 0; }

  // Locomotion at `speed` steering towards world `heading` [rad]; stops path following.
  RequestStatus walk(double speed, double heading);
  // A jump of `length` (then back to locomotion).
  RequestStatus jump(double length);
  // Walks up to world point (x, y, z) and reaches it with the hand: the reach space's parameter
  // is the target's height (clamped, reported), and the reach is placed so that the hand's
  // furthest point lands on the target. Stops path following. kUnknownSpace without a reach or
  // locomotion space.
  RequestStatus reach(double x, double y, double z);
  const ReachStatus& reach_status() const { return reach_status_; }
  // Follows `path` (kept by reference: it must outlive the follow), starting from the closest
  // point to the root.
  void follow(const GroundPath* path);
  void stop_following() { path_ = nullptr; status_.active = false; }
  const FollowStatus& follow_status() const { return status_; }

  void on_tick(Character& character, const CharacterState& state) override;

 private:
  // Where a one-shot motion requested now would put its key point (root at key_t plus
  // `offset` in the root frame there), in the current root frame; and one locomotion cycle's
  // travel at the current speed.
  struct Placement {
    bool found = false;
    double forward = 0, left = 0;  // [m]
    double cycle = 0;              // [m]
  };
  Placement predict(const CharacterState& state, int space, double p, double key_t,
                    const Point2& offset);
  // Whether to request a placed motion now (the goal `goal_forward` metres ahead); otherwise
  // sets the locomotion speed that brings a later opportunity onto the goal.
  bool approach(Character& character, const CharacterState& state, const Placement& placement,
                double goal_forward);
  // The locomotion speed whose cycle travels `travel` metres (clamped to the range), and the
  // inverse.
  double speed_for_cycle(double travel) const;
  double cycle_travel(double speed) const;
  void follow_tick(Character& character, const CharacterState& state);
  void reach_tick(Character& character, const CharacterState& state);

  Character& character_;
  ControllerOptions options_;
  int locomotion_ = -1, jump_ = -1, turning_ = -1, reach_ = -1;
  // Heading control without a path.
  bool steer_heading_ = false;
  double heading_goal_ = 0;
  // Path following.
  const GroundPath* path_ = nullptr;
  FollowStatus status_;
  TransitionSearch search_;  // the jump prediction's scratch
  int current_curve_ = -1;
  int jumped_curve_ = -1;
  bool approaching_ = false;             // the speed is set by a placement, not by the path
  double step_ = 0;                      // [m] the placement staircase's step (measured)
  double last_error_ = 0;                // [m] the placement's last error
  std::array<double, 2> cycle_range_{};  // [m] shortest and longest locomotion cycle
  double last_x_ = 0, last_y_ = 0, last_heading_ = 0;
  double last_jump_t_ = 1;
  // Reach.
  ReachStatus reach_status_;
  Point2 hand_offset_;               // the hand at apex_t, in the reach's root frame there
  BlendedFrame scratch_, scratch0_;  // reach evaluations (allocated once, with a reach space)
};

}  // namespace fourd
