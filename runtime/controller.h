#pragma once
// High-level control of a runtime Character (runtime/character.h): walk or run at a speed and
// heading, jump with a length, and follow a path of contiguous cubic Bezier curves on the
// ground (the paper's Figure 8c).
//
// The controller runs inside the character's tick (Character::TickHook), so its decisions are
// taken at the same motion times whatever the frame rate.
//
// Motions are found by name: options.locomotion_space (cyclic, parameter = speed [m/s]) and
// options.jump_space (one-shot, parameter = length [m]); what the asset lacks is reported by
// has_locomotion() / has_jump() and the matching commands refuse.
//
// Steering. The graphs we build today have no turning space, so the heading is controlled by
// rotating the root gradually (Character::set_turn_rate, at most max_turn_rate): the body keeps
// playing straight locomotion while its root turns, which is honest for gentle curves and looks
// like sliding on tight ones. Path following is pure pursuit: the root aims at the path point
// `lookahead` metres ahead of its closest point, with a turn rate proportional to the heading
// error plus a term on the lateral offset. Speeds along the path come from the curves (a curve
// may carry a speed); a curve marked as a gap is jumped over with its chord as the jump length.
// Because a transition plays the source on to its best exit first, the controller predicts
// where the jump will be: within `jump_search_distance` of the gap it runs the same online
// search the character will run (allocation-free) and predicts the middle of the jump (exit
// distance + the jump's own root travel from its entry to t = 0.5). The search exits at a
// favoured phase of the cycle, so the prediction is a staircase stepping by one cycle's travel;
// the jump is requested on the step nearest to the gap's middle (error up to half a cycle's
// travel, ~0.6 m on the tiny sample: the jump length is not adapted to it yet).
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
  double lookahead = 0.6;        // [m] pure-pursuit look-ahead distance
  double heading_gain = 3.0;     // [1/s] turn rate per radian of heading error
  double lateral_gain = 1.5;     // [rad/s per m] turn rate per metre of lateral offset
  double jump_search_distance = 6.0;  // [m] start predicting the jump this far before a gap
  double arrive_distance = 0.05; // [m] the path is done when this close to its end
  void check() const;            // throws ConfigError naming the field
};

// What the follower measured (for the player's log and the tests).
struct FollowStatus {
  bool active = false;
  bool done = false;
  double s = 0;              // arc length of the root's closest path point [m]
  double lateral_error = 0;  // [m] signed distance of the root from the path (left positive)
  double max_abs_error = 0;  // [m] over the whole follow so far (jumps included)
  double travelled = 0;      // [m] root distance travelled since follow()
  int jumps = 0;
  double predicted_jump_middle = -1;  // [m] arc length where the last requested jump peaks
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

  // Locomotion at `speed` steering towards world `heading` [rad]; stops path following.
  RequestStatus walk(double speed, double heading);
  // A jump of `length` (then back to locomotion).
  RequestStatus jump(double length);
  // Follows `path` (kept by reference: it must outlive the follow), starting from the closest
  // point to the root.
  void follow(const GroundPath* path);
  void stop_following() { path_ = nullptr; status_.active = false; }
  const FollowStatus& follow_status() const { return status_; }

  void on_tick(Character& character, const CharacterState& state) override;

 private:
  Character& character_;
  ControllerOptions options_;
  int locomotion_ = -1, jump_ = -1;
  // Heading control without a path.
  bool steer_heading_ = false;
  double heading_goal_ = 0;
  // Path following.
  const GroundPath* path_ = nullptr;
  FollowStatus status_;
  TransitionSearch search_;  // the jump prediction's scratch
  int current_curve_ = -1;
  int jumped_curve_ = -1;
  double last_x_ = 0, last_y_ = 0;
};

}  // namespace fourd
