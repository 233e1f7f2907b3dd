#pragma once
// A parametric motion space at run time (paper section 3.1): the blended body shape (Eq. 1,
// runtime/blend.h), the blended root motion, the blended timing and the high-level parameter
// map (runtime/parameter_map.h), evaluated at continuous time t in [0, 1] and a parameter p
// with no allocation per call.
//
// Conventions. The body shapes are stored with root motion removed: ground-plane translation
// and heading (rotation about the vertical z axis) are factored out, so the shapes sit at the
// origin facing +x. The root motion of each input is its own curve, relative to its pose at
// t = 0: position (x forward, y left) [m] and heading [rad] in the frame of the root at t = 0.
// Each input also keeps its own clock: seconds[i] is the time of sample i in that input's
// capture, so at weight e_k the space replays take k at its own pace, and a blend advances at
// the blended pace. For a cyclic space sample F - 1 closes the cycle (its shape equals sample 0;
// its root is the displacement of one whole cycle).
//
// File: one versioned binary (pipeline/core/binary_format.h, magic "FOURDMS").
#include <array>
#include <filesystem>
#include <span>
#include <string>
#include <vector>

#include "pipeline/core/binary_format.h"
#include "pipeline/core/mesh.h"
#include "pipeline/core/se2.h"
#include "runtime/blend.h"
#include "runtime/parameter_map.h"

namespace fourd {

struct MotionSpace {
  std::string name;  // motion class, e.g. "locomotion"
  bool cyclic = false;
  std::vector<std::string> takes;  // the N inputs, in parameter order
  double character_height = 0;     // [m] of the template, for errors in % of the body
  std::vector<Tri> triangles;      // the template's topology (#F)
  BlendSpace blend;                // shapes with root motion removed, + hybrid references
  std::vector<RootPose> roots;     // N x F (input-major): root at each sample
  std::vector<float> seconds;      // N x F: the input's own time at each sample [s], from 0
  ParameterMap parameter_map;

  int num_inputs() const { return blend.num_inputs; }
  int num_samples() const { return blend.num_frames; }
  const RootPose& root(int input, int sample) const {
    return roots[static_cast<std::size_t>(input) * blend.num_frames + sample];
  }
  float time(int input, int sample) const {
    return seconds[static_cast<std::size_t>(input) * blend.num_frames + sample];
  }
  // Throws InputError naming what disagrees (sizes, times not increasing, parameter map...).
  void check() const;
};

// One evaluation. Allocate once with make_motion_sample, then evaluate into it every frame.
struct MotionSample {
  BlendedFrame shape;               // body shape at (t, w), root motion removed
  RootPose root;                    // blended root at t, relative to t = 0
  double seconds_per_t = 0;         // blended pace: seconds of motion per unit of t at t
  double duration = 0;              // blended duration of the whole space (t from 0 to 1) [s]
  std::array<float, 3> weights{};   // the blend weights used
  ParameterLookup parameter;        // set by evaluate_motion_space (the p variant)
};
MotionSample make_motion_sample(const MotionSpace& space);

// The blend at time t and weights w (N entries, projected onto the simplex as in blend.h).
void evaluate_motion_space_weights(const MotionSpace& space, double t, std::span<const float> w,
                                   MotionSample* out);
// The blend at time t and high-level parameter p (w = h^-1(p), clamped to the captured range;
// out->parameter says whether it was).
void evaluate_motion_space(const MotionSpace& space, double t, double p, MotionSample* out);

// Only the root / the pace, without blending the shape.
RootPose blended_root(const MotionSpace& space, double t, std::span<const float> w);
double blended_seconds_per_t(const MotionSpace& space, double t, std::span<const float> w);
double blended_duration(const MotionSpace& space, std::span<const float> w);

// Saves atomically / loads, checking magic, version, checksum and consistency. Throws IoError
// or InputError naming the file.
void save_motion_space(const std::filesystem::path& path, const MotionSpace& space);
// The fields of a motion space in the order its file stores them; the runtime asset embeds
// them too, so both files share one layout. The reader checks counts against the bytes left.
void write_motion_space_fields(BinaryWriter& w, const MotionSpace& space);
// What an older file's fields lack: the cells' arc angles (.mspace version 1), the references
// as displacements (.mspace versions 1 and 2, assets before version 4: every reference's frames
// in float, converted here).
struct MotionSpaceLayout {
  bool arc_angles = true;
  bool displacements = true;
};
MotionSpace read_motion_space_fields(BinaryReader& r, MotionSpaceLayout layout);
// An array written by BinaryWriter::write_span (uint64 count, values), into aligned storage.
// Throws InputError naming `what` when the file holds fewer values than announced.
template <class T>
std::vector<T, AlignedAllocator<T>> read_aligned(BinaryReader& r, const char* what);
MotionSpace load_motion_space(const std::filesystem::path& path);

}  // namespace fourd
