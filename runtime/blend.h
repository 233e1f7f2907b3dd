#pragma once
// Real-time blending inside one parametric motion space (paper section 3.1, Eq. 1).
//
// A motion space holds N time-aligned input sequences M_i(t) of one topology (N = 1, 2 or 3)
// and, for hybrid non-linear blending, extra reference sequences M_j(t) = M_NL(t, w_j) at
// intermediate weights w_j, precomputed offline (stages/motionspace/hybrid_build.h). The
// references tile the weight simplex with cells: segments of the weight line for N = 2,
// triangles of the barycentric weight triangle for N = 3. At run time
//
//   M(t, w) = sum_j g(w, w_j) M_j(t)                                                    (Eq. 1)
//
// with g the barycentric coordinates of w inside the cell that contains it (zero for every
// other reference). The paper writes each reference as M_L(t, w_j) + D_NL(t, w_j); since M_L
// is linear in w and sum_j g_j w_j = w, Eq. 1 equals M_L(t, w) + sum_j g_j D_NL(t, w_j). We
// store the reference meshes M_j themselves rather than D_NL: the result is identical, but an
// evaluation reads only the cell's corners (2 or 3 frames per time sample) instead of the N
// inputs plus the displacements. D_NL(t, w_j) is M_j(t) - M_L(t, w_j) whenever it is wanted.
//
// Data layout (struct of arrays, float): one frame of one reference is three planes x | y | z
// of `plane_stride` floats each (the vertex count rounded up to 16, so every plane starts on a
// 64-byte boundary); the frames of all references follow each other in one aligned array.
// Time is continuous: t in [0, 1] maps to frame position t (F - 1), and an evaluation blends
// the two nearest frames linearly. Evaluations allocate nothing: the caller owns the output.
#include <array>
#include <cstddef>
#include <cstdlib>
#include <new>
#include <span>
#include <vector>

#include "pipeline/core/mesh.h"

namespace fourd {

// Allocator for SIMD-friendly arrays: every allocation starts on a 64-byte boundary.
template <class T>
struct AlignedAllocator {
  using value_type = T;
  static constexpr std::align_val_t kAlignment{64};
  AlignedAllocator() = default;
  template <class U>
  AlignedAllocator(const AlignedAllocator<U>&) {}
  T* allocate(std::size_t n) { return static_cast<T*>(::operator new(n * sizeof(T), kAlignment)); }
  void deallocate(T* p, std::size_t) { ::operator delete(p, kAlignment); }
  template <class U>
  bool operator==(const AlignedAllocator<U>&) const {
    return true;
  }
};
using AlignedFloats = std::vector<float, AlignedAllocator<float>>;

// Floats per plane: the vertex count rounded up to a multiple of 16 (one cache line).
int blend_plane_stride(int num_vertices);

struct BlendSpace {
  int num_inputs = 0;    // N, 1..3
  int num_vertices = 0;  // #V
  int num_frames = 0;    // F >= 1; frame f sits at t = f / (F - 1)
  int plane_stride = 0;  // blend_plane_stride(num_vertices)

  // Weights of every reference, N per reference, non-negative and summing to 1. References
  // 0..N-1 are the inputs themselves (weights e_i); hybrid_build appends the others.
  std::vector<double> reference_weights;  // #R x N
  // Positions of every reference at every frame: [reference][frame][x | y | z planes].
  AlignedFloats frames;
  // Cells tiling the weight simplex, as reference indices: N = 1: {0, -1, -1}; N = 2: weight
  // segments {a, b, -1}; N = 3: weight triangles {a, b, c}. Cells meet edge to edge, so the
  // blend is continuous in w.
  std::vector<std::array<int, 3>> cells;

  int num_references() const {
    return num_inputs == 0 ? 0 : static_cast<int>(reference_weights.size()) / num_inputs;
  }
  std::size_t frame_stride() const { return 3 * static_cast<std::size_t>(plane_stride); }
  const float* frame(int reference, int f) const {
    return frames.data() + (static_cast<std::size_t>(reference) * num_frames + f) * frame_stride();
  }
  float* frame(int reference, int f) {
    return frames.data() + (static_cast<std::size_t>(reference) * num_frames + f) * frame_stride();
  }
  // Throws InputError if sizes disagree, a weight is off the simplex or a cell is invalid.
  void check() const;
};

// A space with the N inputs as its only references (frames zeroed, to be filled with
// set_frame) and the single cell spanning the whole simplex.
BlendSpace make_blend_space(int num_inputs, int num_vertices, int num_frames);
// Appends a reference at weights `w` (N values, summing to 1) with zeroed frames; returns its
// index. Does not change the cells.
int add_reference(BlendSpace* space, std::span<const double> w);
// Copies #V positions into frame f of a reference (e.g. positions of a Mesh).
void set_frame(BlendSpace* space, int reference, int f, std::span<const Vec3f> positions);

// One blended frame: planes x | y | z with `plane_stride` floats each (num_vertices valid).
struct BlendedFrame {
  int num_vertices = 0;
  int plane_stride = 0;
  AlignedFloats data;  // 3 * plane_stride
  const float* x() const { return data.data(); }
  const float* y() const { return data.data() + plane_stride; }
  const float* z() const { return data.data() + 2 * static_cast<std::size_t>(plane_stride); }
  Vec3f position(int v) const { return {x()[v], y()[v], z()[v]}; }
};
// Allocates an output frame for `space` (once, before the frame loop).
BlendedFrame make_blended_frame(const BlendSpace& space);
// Copies the blended positions into `positions` (resized to #V: no allocation when it is
// already that size).
void copy_positions(const BlendedFrame& frame, std::vector<Vec3f>* positions);

// What one evaluation reads: up to kMaxBlendSources frames and their coefficients; the output
// is sum_k coefficients[k] * sources[k] over 3 * plane_stride floats.
inline constexpr int kMaxBlendSources = 6;  // 3 cell corners x 2 time samples
struct BlendSources {
  int count = 0;
  std::array<const float*, kMaxBlendSources> sources{};
  std::array<float, kMaxBlendSources> coefficients{};
};

// Weights handed to an evaluation are projected onto the simplex: negative entries count as
// zero and the rest is divided by its sum (the 1 / sum w_i of the paper's linear blend); an
// all-zero weight vector means equal weights. `w` has N entries.

// The frames and coefficients of the hybrid blend M(t, w) (Eq. 1) and of the linear blend
// M_L(t, w) = sum_i w_i M_i(t) / sum_i w_i. Frames with a zero coefficient are left out.
void hybrid_blend_sources(const BlendSpace& space, double t, std::span<const float> w,
                          BlendSources* out);
void linear_blend_sources(const BlendSpace& space, double t, std::span<const float> w,
                          BlendSources* out);

// out[0 .. n) = sum_k coefficients[k] * sources[k][0 .. n): the memory-bound kernel.
void weighted_sum(const BlendSources& sources, std::size_t n, float* out);

// Hybrid non-linear blend at continuous time t in [0, 1] and weights w (Eq. 1). No allocation.
void blend_hybrid(const BlendSpace& space, double t, std::span<const float> w, BlendedFrame* out);
// Linear blend of the N inputs at continuous time t in [0, 1]. No allocation.
void blend_linear(const BlendSpace& space, double t, std::span<const float> w, BlendedFrame* out);

}  // namespace fourd
