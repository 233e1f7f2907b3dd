#pragma once
// Real-time blending inside one parametric motion space (paper section 3.1, Eq. 1).
//
// A motion space holds N time-aligned input sequences M_i(t) of one topology (N = 1, 2 or 3)
// and, for hybrid non-linear blending, extra reference sequences M_j(t) = M_NL(t, w_j) at
// intermediate weights w_j, precomputed offline (stages/motionspace/hybrid_build.h). Cells tile
// the weight simplex: segments of the weight line for N = 2, triangles of the barycentric
// weight triangle for N = 3. At run time
//
//   M(t, w) = sum_j g(w, w_j) M_j(t)                                                    (Eq. 1)
//
// where g(., w_j) is zero for every reference outside the cell that contains w and, inside it,
// the QUADRATIC (P2 Lagrange) shape function of node j of that cell. A cell's nodes are its
// corners and the midpoints of its edges: a segment with corners a, b and midpoint m is a
// 3-node P2 segment, g = (1 - s)(1 - 2s), 4 s (1 - s), s (2s - 1) at local coordinate s; a
// triangle is a 6-node P2 triangle, g = lambda_i (2 lambda_i - 1) at corner i and
// 4 lambda_i lambda_k at the midpoint of edge (i, k), with lambda the barycentric coordinates
// of w in the cell. The midpoint nodes are found by weight: the reference whose w_j is exactly
// the midpoint of the edge's ends. An edge without such a reference is interpolated linearly
// (its missing midpoint counts as the mean of its ends: g_m / 2 goes to each end), so a cell
// with no midpoint reference is the paper's linear interpolation of its corners and a space
// with only its inputs is the linear blend. Quadratic cells follow the arc that a rotation-
// dominated displacement D_NL(w) draws against its chord (on a segment with D = 0 at both ends,
// D(s) ~ 4 s (1 - s) D(1/2)); interpolating it linearly leaves the arc's sagitta as error.
// Neighbouring cells share an edge's three nodes, so the blend stays continuous in w.
//
// Arc segments (2 inputs). A quadratic follows the arc's sagitta but not its uneven pace along
// the chord (a point turning at a constant rate moves fast across the chord's middle and slowly
// near its ends): the leftover, odd about the midpoint, is cubic in the rotation angle and
// dominates the error of a strongly rotating blend. A segment may therefore carry an arc angle
// theta (cell_arc_angles, set offline from the node meshes): its g is then the trigonometric
// Lagrange basis on nodes phi = 0, theta / 2, theta at phi = theta s,
//   g_j(s) = prod_{k != j} sin((phi - phi_k) / 2) / sin((phi_j - phi_k) / 2),
// which spans {1, cos phi, sin phi}: it reproduces exactly any vertex that turns by theta on a
// circle, still sums to 1 and interpolates the three nodes, and tends to the quadratic basis as
// theta -> 0 (theta = 0 is the quadratic). It is still Eq. 1 with one g per cell node.
//
// Storage (Eq. 1 as the paper writes it). The paper writes each reference as
// M_j = M_L(t, w_j) + D_j(t): the linear blend of the N inputs at the reference's weights plus
// a displacement. M_L is linear in w, so
//   M(t, w) = sum_j g_j (M_L(t, w_j) + D_j(t)) = sum_k a_k M_k(t) + sum_{j >= N} g_j D_j(t),
//   a_k = sum_j g_j w_{j,k}   (over every node j of the cell, inputs included),
// exact for any basis (the arc basis too; with the P2 basis, sum_j g_j w_j = w and this is the
// linear blend M_L(t, w) plus the interpolated displacement). Inputs have D = 0.
// We store the N input frames in float and, for every other reference, only D_j, in IEEE half
// precision (fp16): an evaluation is memory-bound, and a displacement is small (centimetres to
// a few decimetres, the gap between the non-linear and the linear blend), so fp16's 11-bit
// significand keeps it to < 0.2 mm at 0.4 m while reading half the bytes. The top P2 cell of 3 inputs reads 6 float
// frames (3 inputs x 2 time samples) and 6 half frames (3 midpoints x 2) instead of 12 float
// frames: 3/4 of the bytes. The reference mesh M_j(f) = M_L(f, w_j) + D_j(f) is
// reference_frame() whenever it is wanted. Offline, set_frame() takes a reference's mesh and
// stores its displacement from the inputs' frames, so the inputs' frames must be set first (it
// refuses an input frame once the space has references); displacements beyond fp16's range
// (|D| > 65504) or not finite are refused.
// Some g_j are negative (a corner's g dips to -1/8 near its opposite nodes); that is expected.
//
// Data layout (struct of arrays): one frame is three planes x | y | z of `plane_stride` values
// each (the vertex count rounded up to 16, so every float plane starts on a 64-byte boundary);
// the frames of the inputs follow each other in one aligned float array, the displacements of
// the other references in one aligned array of fp16 values.
// Time is continuous: t in [0, 1] maps to frame position t (F - 1), and an evaluation blends
// the two nearest frames linearly. Evaluations allocate nothing: the caller owns the output.
#include <array>
#include <bit>
#include <cstddef>
#include <cstdint>
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
// IEEE 754 binary16 values (their bit patterns).
using AlignedHalfs = std::vector<std::uint16_t, AlignedAllocator<std::uint16_t>>;

// The largest finite half.
inline constexpr float kMaxHalf = 65504.f;
// Float to half, rounded to nearest (ties to even); beyond kMaxHalf: infinity; NaN stays NaN.
std::uint16_t float_to_half(float x);
// Half to float, exact (zeros, subnormals, infinities and NaN included). Branch-free, so loops
// over it vectorise; no float subnormal is formed, so it holds with denormals-are-zero too.
inline float half_to_float(std::uint16_t h) {
  const std::uint32_t exponent = h & 0x7c00u;
  std::uint32_t bits = (static_cast<std::uint32_t>(h & 0x7fffu) << 13) + (112u << 23);  // rebias
  bits |= exponent == 0x7c00u ? 0x7f800000u : 0u;  // infinity, NaN
  // Zero and subnormals: read as 2^-14 (1 + m / 1024), minus the 2^-14 = m 2^-24 exactly.
  const float subnormal =
      std::bit_cast<float>(bits + (1u << 23)) - std::bit_cast<float>(113u << 23);
  const float f = exponent == 0 ? subnormal : std::bit_cast<float>(bits);
  return std::bit_cast<float>(std::bit_cast<std::uint32_t>(f) |
                              (static_cast<std::uint32_t>(h & 0x8000u) << 16));
}

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
  // Positions of the inputs at every frame: [input][frame][x | y | z planes].
  AlignedFloats frames;
  // Displacements D_j(f) = M_j(f) - M_L(f, w_j) of the other references at every frame, fp16:
  // [reference - N][frame][x | y | z planes].
  AlignedHalfs displacements;
  // Empty, or the displacements decoded to float, in the same layout (decode_displacements):
  // evaluations then read these instead of the halves. For targets without a half-to-float
  // instruction (the web build: WebAssembly SIMD has none), where converting every value of
  // every evaluation costs more than reading twice the bytes.
  AlignedFloats displacement_floats;
  // Cells tiling the weight simplex, as the reference indices of their corners: N = 1:
  // {0, -1, -1}; N = 2: weight segments {a, b, -1}; N = 3: weight triangles {a, b, c}. Cells
  // meet edge to edge (no reference inside an edge except its midpoint node), so the blend is
  // continuous in w. The midpoint nodes are not listed: see cell_midpoints.
  std::vector<std::array<int, 3>> cells;
  // Per cell, the arc angle theta [rad] of a 2-input segment's shape functions (see above), in
  // [0, pi]; 0: quadratic. Empty: every cell quadratic. Must be 0 for triangles.
  std::vector<double> cell_arc_angles;
  double cell_arc_angle(int cell) const {
    return cell_arc_angles.empty() ? 0.0 : cell_arc_angles[cell];
  }

  int num_references() const {
    return num_inputs == 0 ? 0 : static_cast<int>(reference_weights.size()) / num_inputs;
  }
  std::size_t frame_stride() const { return 3 * static_cast<std::size_t>(plane_stride); }
  // Frame f of input `input` (< N).
  const float* frame(int input, int f) const {
    return frames.data() + (static_cast<std::size_t>(input) * num_frames + f) * frame_stride();
  }
  float* frame(int input, int f) {
    return frames.data() + (static_cast<std::size_t>(input) * num_frames + f) * frame_stride();
  }
  // Displacement of reference `reference` (>= N) at frame f.
  const std::uint16_t* displacement(int reference, int f) const {
    return displacements.data() +
           (static_cast<std::size_t>(reference - num_inputs) * num_frames + f) * frame_stride();
  }
  std::uint16_t* displacement(int reference, int f) {
    return displacements.data() +
           (static_cast<std::size_t>(reference - num_inputs) * num_frames + f) * frame_stride();
  }
  // The decoded twin of a displacement frame (decode_displacements), or null.
  const float* displacement_float(const std::uint16_t* displacement_frame) const {
    return displacement_floats.empty()
               ? nullptr
               : displacement_floats.data() + (displacement_frame - displacements.data());
  }
  // Throws InputError if sizes disagree, a weight is off the simplex or a cell is invalid.
  void check() const;
};

// Fills space.displacement_floats with every displacement converted to float (exactly:
// half_to_float), so evaluations read floats: the same results, twice the memory of the
// halves. Call again after changing the displacements.
void decode_displacements(const AlignedHalfs& halves, AlignedFloats* floats);
inline void decode_displacements(BlendSpace* space) {
  decode_displacements(space->displacements, &space->displacement_floats);
}

// A space with the N inputs as its only references (frames zeroed, to be filled with
// set_frame) and the single cell spanning the whole simplex.
BlendSpace make_blend_space(int num_inputs, int num_vertices, int num_frames);
// Appends a reference at weights `w` (N values, summing to 1) with zero displacements (its mesh
// is the linear blend until set_frame); returns its index. Does not change the cells.
int add_reference(BlendSpace* space, std::span<const double> w);
// Drops the references from `count` (>= N) on; cells are left as they are.
void truncate_references(BlendSpace* space, int count);
// Frame f of a reference from its #V positions (e.g. those of a Mesh): an input's positions,
// or the displacement of another reference's mesh from the linear blend of the inputs' frame f
// at its weights. Throws InputError for bad indices or sizes, for an input once the space has
// other references (their displacements are relative to the inputs: set the inputs first), and
// for a displacement beyond fp16's range or not finite. Different (reference, f) may be set
// from different threads.
void set_frame(BlendSpace* space, int reference, int f, std::span<const Vec3f> positions);
// The mesh of any reference at frame f, M_j(f) (for j >= N: M_L(f, w_j) + D_j(f)), as planes
// x | y | z into out[0 .. frame_stride).
void reference_frame(const BlendSpace& space, int reference, int f, float* out);
// From frames of every reference in float, [reference][frame][x | y | z planes] (#R x F frames
// in the space's layout: older files, or another per-vertex quantity blended like the positions,
// e.g. normals), the inputs' frames and the other references' fp16 displacements from the
// linear blend of the inputs at their weights. Throws InputError if the sizes disagree with the
// space's, or a displacement is beyond fp16's range or not finite.
void split_reference_frames(const BlendSpace& space, std::span<const float> all,
                            AlignedFloats* inputs, AlignedHalfs* displacements);

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

// What one evaluation reads: up to kMaxBlendSources float frames (the inputs) and up to
// kMaxBlendDisplacements fp16 frames (the displacements), with their coefficients; the output
// is sum_k coefficients[k] * sources[k] + sum_k displacement_coefficients[k] *
// displacement_sources[k] over 3 * plane_stride values.
inline constexpr int kMaxBlendSources = 6;         // 3 inputs x 2 time samples
inline constexpr int kMaxBlendDisplacements = 12;  // 6 nodes of a P2 triangle x 2 time samples
struct BlendSources {
  int count = 0;
  std::array<const float*, kMaxBlendSources> sources{};
  std::array<float, kMaxBlendSources> coefficients{};
  int displacement_count = 0;
  std::array<const std::uint16_t*, kMaxBlendDisplacements> displacement_sources{};
  std::array<float, kMaxBlendDisplacements> displacement_coefficients{};
  // With decoded displacements (BlendSpace::displacement_floats): the same frames in float,
  // which the kernel then reads instead of displacement_sources; otherwise null.
  std::array<const float*, kMaxBlendDisplacements> displacement_floats{};
  bool decoded() const { return displacement_count > 0 && displacement_floats[0] != nullptr; }
  // Bytes read for `values` values per frame.
  std::size_t read_bytes(std::size_t values) const {
    return values * (count * sizeof(float) +
                     displacement_count * (decoded() ? sizeof(float) : sizeof(std::uint16_t)));
  }
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

// out[0 .. n) = the sum BlendSources describes: the memory-bound kernel. At least one source.
void weighted_sum(const BlendSources& sources, std::size_t n, float* out);
// out[0 .. n) += the same sum (e.g. a cross-fade's second blend).
void accumulate_weighted_sum(const BlendSources& sources, std::size_t n, float* out);
// The same two, always with the kernel compiled for baseline x86-64 (which weighted_sum uses on
// CPUs without AVX2, FMA and F16C), so tests check it on any CPU.
void portable_weighted_sum(const BlendSources& sources, std::size_t n, bool accumulate,
                           float* out);
// Whether this CPU runs the kernels' AVX2 + FMA + F16C variant (chosen once at run time;
// otherwise the baseline x86-64 one runs).
bool cpu_has_avx2_fma_f16c();

// The node layout of one cell. midpoints[k] is the reference at the midpoint of the edge
// opposite corner k (triangles: edges (1, 2), (2, 0), (0, 1)); segments use midpoints[0] for
// edge (0, 1). -1 where no reference sits at the midpoint (that edge is linear).
std::array<int, 3> cell_midpoints(const BlendSpace& space, const std::array<int, 3>& cell);
// The reference whose weights equal `w` (N values, to 1e-9), or -1.
int find_reference(const BlendSpace& space, std::span<const double> w);

// The references and the shape functions g of Eq. 1 inside one cell at barycentric
// coordinates `lambda` (N values used; they sum to 1): corners first, then the midpoint nodes
// present; entries with g = 0 are left out (count: at most 6). `arc_angle` is the cell's
// (BlendSpace::cell_arc_angle): for a segment with its midpoint, the arc basis; else ignored.
struct CellNodes {
  int count = 0;
  std::array<int, 6> references{};
  std::array<double, 6> g{};
};
void cell_shape_functions(const BlendSpace& space, const std::array<int, 3>& cell,
                          const std::array<int, 3>& midpoints, const std::array<double, 3>& lambda,
                          double arc_angle, CellNodes* out);

// Hybrid non-linear blend at continuous time t in [0, 1] and weights w (Eq. 1). No allocation.
void blend_hybrid(const BlendSpace& space, double t, std::span<const float> w, BlendedFrame* out);
// Linear blend of the N inputs at continuous time t in [0, 1]. No allocation.
void blend_linear(const BlendSpace& space, double t, std::span<const float> w, BlendedFrame* out);

}  // namespace fourd
