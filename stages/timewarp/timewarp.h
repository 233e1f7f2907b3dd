#pragma once
// The timewarp stage: for each motion class of session.yaml, separates root motion from body
// shape, extracts closed cycles of cyclic takes, registers the takes in time (time_warp.h) and
// resamples them at common times t_i = i / (F - 1), so that corresponding poses of every take
// share t. Reads the align stage's output (align/template.ply + align/<take>/<frame>.ply, one
// topology), or oracle/align/ in oracle mode.
//
// Writes, per class, into timewarp/ (timewarp_oracle/ in oracle mode):
//   <class>.twarp   the resampled class (timewarp_io.h), read by the motionspace stage
//   <class>.json    per take: cycle, phase offset, the t of every captured frame, root motion
//   report.json     per class and take: period, every cycle that closes, one-shot segments
// and options.yaml (the options used). Every class is computed before anything is written, and
// the folder is replaced as a whole, so a failure leaves the previous outputs untouched.
#include <Eigen/Core>
#include <filesystem>
#include <string>
#include <vector>

#include "pipeline/core/config.h"
#include "pipeline/core/mesh.h"
#include "pipeline/core/session.h"
#include "pipeline/exchange/aligned_input.h"
#include "pipeline/exchange/warped_class.h"
#include "stages/common/stage.h"
#include "stages/timewarp/time_warp.h"

namespace fourd::timewarp {

// The options are the members visit() lists, with their help; the others are tuned values,
// not options (docs/timewarp.md, "Advanced").
struct TimewarpOptions {
  int samples = 0;
  int min_cycle_frames = 4;
  double max_closure_ratio = 0.3;
  int oversample = 4;              // DTW phase samples per frame
  double velocity_weight = 0.01;   // weight of the phase velocity in the DTW distance [cycle^2]
  double slope_penalty = 0.1;      // extra cost of non-diagonal DTW steps
  int smoothing = 2;               // smoothing passes over the DTW path
  bool center_poses = true;        // DTW on deviations from each take's mean pose (not on the
                                   // poses themselves)
  int root_smoothing = 8;          // [1 2 1] passes over each take's root curve (sigma 2 frames):
                                   // damps frame-to-frame alignment jitter
  template <class V>
  void visit(V& v) {
    v("samples", samples, "samples per class (0: one per frame of the longest take)",
      Range{0, 100000});
    v("min_cycle_frames", min_cycle_frames, "shortest cycle considered [frames]",
      Range{2, 100000});
    v("max_closure_ratio", max_closure_ratio,
      "a cycle's closure RMS over its pose variation, at most", Range{0, 10});
  }
  CycleOptions cycle() const { return {min_cycle_frames, max_closure_ratio}; }
  WarpOptions warp() const {
    return {oversample, velocity_weight, slope_penalty, smoothing, center_poses};
  }
};



// Removes root motion from a take's frames.
// `root_smoothing`: passes of smooth_roots() over the estimated root curve.
LocalTake make_local_take(const std::string& name, std::vector<Eigen::Matrix3Xd> frames,
                          const Eigen::Matrix3Xd& template_positions,
                          const std::vector<double>& torso, int root_smoothing = 0);

// Registers and resamples one class. Throws InputError for a class with fewer than 2 or more
// than 3 takes, takes that do not fit together, or a cycle that cannot be closed (naming it).
WarpedClass warp_class(const MotionClassConfig& motion, double fps, const Mesh& template_mesh,
                       std::vector<LocalTake> takes, const TimewarpOptions& options);

void run_timewarp(const Session& session, const StageArgs& args);

}  // namespace fourd::timewarp
