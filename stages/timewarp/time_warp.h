#pragma once
// Time registration of the takes of one motion class (paper section 3.1: t = f(t_i), so that
// corresponding poses of every take share t in [0, 1]).
//
// Every take is first seen as a function of a phase u:
//  - one-shot (jump, reach): u in [0, 1] spans the whole take, frame x = u (n - 1);
//  - cyclic (walk, run, turn): one complete cycle [start, start + period] of the take (found by
//    find_cycle, fractional frames) is a periodic function of u: frame x = start + frac(u)
//    period. Its shape is corrected for the small closure residual (the gap between the shapes
//    at the cycle's ends is spread linearly over the cycle), so the cycle's end joins its start
//    exactly; its root keeps accumulating whole cycles (u >= 1 is the next cycle).
// Takes are then registered to the class's first take (the reference) by dynamic time warping
// over a distance of root-free shape and phase velocity sampled `oversample` times per frame;
// for cycles, a phase offset is found first by a circular search (refined to a fraction of a
// sample), then DTW runs from that offset once around the cycle.
#include <Eigen/Core>
#include <span>
#include <string>
#include <vector>

#include "pipeline/exchange/root_motion.h"
#include "pipeline/exchange/warped_class.h"

namespace fourd::timewarp {

// One take with its root motion removed, frame by frame.
struct LocalTake {
  std::string name;
  std::vector<Eigen::Matrix3Xd> shapes;  // #frames, 3 x #V each, root removed
  std::vector<RootTransform> roots;              // #frames, headings unwrapped
  // The per-frame roots before smoothing (empty: as `roots`). A cycle's mean motion is taken
  // from them: smoothing pins the take's ends, so its output is not periodic there.
  std::vector<RootTransform> raw_roots;
  int num_frames() const { return static_cast<int>(shapes.size()); }
};

// Linear interpolation at a continuous frame position x (clamped to [0, n - 1]).
Eigen::Matrix3Xd shape_at(const LocalTake& take, double x);
RootTransform root_at(const LocalTake& take, double x);

// Mean squared vertex distance [m^2].
double shape_distance(const Eigen::Matrix3Xd& a, const Eigen::Matrix3Xd& b);

struct CycleOptions {
  int min_cycle_frames = 4;        // shortest cycle considered [frames]
  double max_closure_ratio = 0.3;  // closure / variation of the cycle's state, at most
};


// The period of a take [frames, fractional], from all of it: the lag at which the state
// (shape and velocity) repeats best on average over every pair of frames that lag apart, taken
// down to the shortest sub-multiple at which the state repeats about as well (and at every
// multiple of it the take holds), so that a motion whose shape nearly repeats at half its
// period (a quadruped's limb pairs in antiphase) is not cut at the half; then refined to a
// fraction of a frame. Throws InputError naming the take if it is shorter than
// min_cycle_frames + 1 frames.
// A loose part of the surface that moves a lot but repeats at no lag (a skirt's chaotic swing,
// hair) is left out of the scores of find_period, find_cycle and find_cycles, as long as it is
// less than half the vertices; a Cycle's closure and variation are then the rest's.
double find_period(const LocalTake& take, const CycleOptions& options);

// The best complete cycle of a cyclic take: find_period's period, started where the closure
// distance is smallest. Throws InputError naming the take if it is shorter than
// min_cycle_frames + 1 frames or its best cycle cannot be closed (closure_ratio above
// max_closure_ratio).
Cycle find_cycle(const LocalTake& take, const CycleOptions& options);

// A long take cut into what loops and what does not: every good cycle (closure_ratio at most
// max_closure_ratio; each start's best length within 15 % of the period, as a long take's pace
// drifts; the best closing first, none overlapping another), and the frames between them
// (at least min_cycle_frames long) as one-shot segments. A take too short for a cycle, or
// without one, is one one-shot segment. Does not throw.
struct FrameRange {
  int first = 0, last = 0;  // frames, inclusive
};
struct TakeSegments {
  double period = 0;               // find_period's (0: the take is too short)
  std::vector<Cycle> cycles;       // by start frame
  std::vector<FrameRange> one_shots;
};
TakeSegments find_cycles(const LocalTake& take, const CycleOptions& options);

TakeTiming one_shot_timing(const LocalTake& take);
TakeTiming cyclic_timing(const Cycle& cycle);

// Shape (closure-corrected for cycles) and world root at phase u.
Eigen::Matrix3Xd shape_at_phase(const LocalTake& take, const TakeTiming& timing, double u);
RootTransform root_at_phase(const LocalTake& take, const TakeTiming& timing, double u);

// The steady root of a cyclic take: the body's trajectory without its per-step sway. The
// per-frame roots (the torso's position and facing) weave from side to side and twist with
// every step; a character that integrates them weaves too and covers more ground than it
// advances. The steady root turns at a constant rate along a circular arc (or a straight
// line): per cycle it moves by the take's mean motion W (root(x + period) root(x)^-1 averaged
// over every frame x that has a frame one period later and, where any is left, whose
// [x, x + period] closes as a cycle (closure_ratio at most options.max_closure_ratio): not in
// or across a long take's stands), and it runs through the middle of the
// sway (over the cycle [start, start + period], its heading and position average to the
// per-frame roots'). Returns the take re-rooted: these roots, and the shapes expressed
// relative to them (the frames themselves unchanged), so the sway is kept in the body shape.
LocalTake steady_cycle_root(LocalTake take, const TakeTiming& timing, const CycleOptions& options = {});

Warp identity_warp(int intervals);

struct WarpOptions {
  int oversample = 4;            // phase samples per frame of the reference take
  double velocity_weight = 0.01; // weight of the phase-velocity term of the distance [cycle^2]
  double slope_penalty = 0.1;    // extra cost of non-diagonal DTW steps (relative)
  int smoothing = 2;             // [1 2 1] smoothing passes over the DTW path
  bool center_poses = true;      // compare poses as deviations from each take's mean pose
};

// Registers `take` to the reference take. Both timings must be of the same kind.
Warp register_take(const LocalTake& reference, const TakeTiming& reference_timing,
                   const LocalTake& take, const TakeTiming& timing, const WarpOptions& options);

}  // namespace fourd::timewarp
