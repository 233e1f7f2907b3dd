#pragma once
// The registered, resampled takes of one motion class that the timewarp stage hands the
// motionspace stage: timewarp/<class>.twarp, a versioned binary file
// (pipeline/core/binary_format.h, magic "FOURDTW"). The time registration itself is
// stages/timewarp/time_warp.h's.
#include <Eigen/Core>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "pipeline/core/mesh.h"
#include "pipeline/exchange/root_motion.h"

namespace fourd {

// A cycle is judged on the body's state, its shape and its velocity: a take cut at two poses
// that look alike but move differently (a swing forward and the swing back) does not close.
// Velocities are per frame, weighted by (period / 2 pi)^2 so both terms have the scale of a
// shape (for a sinusoidal motion they vary equally).
struct Cycle {
  double start = 0;          // first frame of the cycle (fractional)
  double period = 0;         // cycle length [frames] (fractional)
  double closure_rms = 0;    // RMS vertex distance between the shapes at start and end [m]
  double variation_rms = 0;  // RMS vertex distance of the cycle's shapes from their mean [m]
  double closure_ratio = 0;  // state closure / state variation over the cycle
};

// Where a take's phase lives in its frames (stages/timewarp/time_warp.h explains the phase).
struct TakeTiming {
  bool cyclic = false;
  double start = 0;   // cyclic: cycle start frame; one-shot: 0
  double length = 0;  // cyclic: period [frames]; one-shot: n - 1
  double frame_at(double u) const;  // continuous frame position of phase u
};

// A monotone map from the reference's phase to a take's phase: the take's phase at reference
// phase u in [0, 1] is offset + knots interpolated at u (knots from 0 to 1, M + 1 of them,
// strictly increasing). The reference take's own warp is the identity.
struct Warp {
  double offset = 0;           // cyclic: phase of the take at the reference's phase 0
  std::vector<double> knots;   // M + 1 values at u = i / M
  double at(double u) const;        // offset + knots(u)
  double inverse(double v) const;   // u with knots(u) = v - offset (v - offset in [0, 1])
};

// One take of a registered class.
struct WarpedTake {
  std::string name;
  int num_frames = 0;            // captured frames of the take
  Cycle cycle;                   // cyclic classes only
  TakeTiming timing;
  Warp warp;                     // reference phase -> this take's phase
  std::vector<double> frame_t;   // the class time t of every captured frame (cycles: wrapped)
  // Per sample i (t_i = i / (F - 1)):
  std::vector<double> sample_frames;  // F: continuous frame position in the take
  std::vector<double> seconds;        // F: the take's own time since sample 0 [s]
  std::vector<RootTransform> roots;           // F: root relative to sample 0
  std::vector<Vec3f> shapes;          // F x #V (sample-major): body shape, root removed
};

struct WarpedClass {
  std::string name;
  std::string parameter;
  bool cyclic = false;
  double fps = 0;
  int num_vertices = 0;
  int num_samples = 0;                  // F
  std::vector<Tri> triangles;           // the template's
  Eigen::Matrix3Xd template_positions;  // 3 x #V
  double character_height = 0;          // [m]
  std::vector<WarpedTake> takes;        // reference first

  // Shape of take k at sample i as a 3 x #V matrix.
  Eigen::Matrix3Xd shape(int take, int sample) const;
};

void write_warped_class(const std::filesystem::path& path, const WarpedClass& warped);
// Throws IoError / InputError naming the file for a missing, corrupt or inconsistent file.
WarpedClass read_warped_class(const std::filesystem::path& path);

nlohmann::json warped_class_summary(const WarpedClass& warped);

}  // namespace fourd
