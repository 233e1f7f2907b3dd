#include "runtime/blend.h"

#include <fmt/format.h>

#include <algorithm>
#include <bit>
#include <cassert>
#include <cmath>
#include <numbers>
#include <utility>

#if defined(__GNUC__) && defined(__x86_64__)
#include <immintrin.h>
#include <cpuid.h>
#endif
#if defined(__wasm_simd128__)
#include <wasm_simd128.h>
#endif

#include "pipeline/core/error.h"

namespace fourd {

namespace {

constexpr int kPadFloats = 16;

// Tolerance for weights that should sum to 1 or be non-negative (they come from files).
constexpr double kWeightTolerance = 1e-6;

// Arc angles below this use the quadratic basis, the arc basis's limit (and its exact value to
// double precision for such angles: the difference is O(theta^2) relative).
constexpr double kMinArcAngle = 1e-6;

// Projects w onto the simplex as the header describes; returns N values in `p`.
void normalised_weights(std::span<const float> w, int n, std::array<double, 3>* p) {
  assert(static_cast<int>(w.size()) >= n);
  double sum = 0;
  for (int i = 0; i < n; ++i) {
    (*p)[i] = std::max(0.0, static_cast<double>(w[i]));
    sum += (*p)[i];
  }
  for (int i = 0; i < n; ++i) (*p)[i] = sum > 0 ? (*p)[i] / sum : 1.0 / n;
}

// Barycentric coordinates of w (on the simplex) in one cell; unused entries are 0.
std::array<double, 3> cell_coordinates(const BlendSpace& space, const std::array<int, 3>& cell,
                                       const std::array<double, 3>& w) {
  const int n = space.num_inputs;
  const double* rw = space.reference_weights.data();
  if (n == 1) return {1.0, 0.0, 0.0};
  if (n == 2) {
    // The weight line is parametrised by s = w_1 (w_0 = 1 - s).
    const double sa = rw[cell[0] * 2 + 1], sb = rw[cell[1] * 2 + 1];
    const double gb = (w[1] - sa) / (sb - sa);
    return {1.0 - gb, gb, 0.0};
  }
  // N = 3: solve [wb - wa, wc - wa] (gb, gc) = w - wa in the (w_1, w_2) plane.
  const double* a = rw + cell[0] * 3;
  const double* b = rw + cell[1] * 3;
  const double* c = rw + cell[2] * 3;
  const double e1x = b[1] - a[1], e1y = b[2] - a[2];
  const double e2x = c[1] - a[1], e2y = c[2] - a[2];
  const double dx = w[1] - a[1], dy = w[2] - a[2];
  const double det = e1x * e2y - e2x * e1y;
  const double gb = (dx * e2y - e2x * dy) / det;
  const double gc = (e1x * dy - dx * e1y) / det;
  return {1.0 - gb - gc, gb, gc};
}

// The cell containing w and w's coordinates in it. Cells are few (tens at most), so a scan is
// cheaper than any search structure. The first cell containing w wins (on a shared edge both
// give the same blend); if rounding put w just outside every cell, the nearest one does.
int locate_cell(const BlendSpace& space, const std::array<double, 3>& w, std::array<double, 3>* g) {
  const int corners = std::min(space.num_inputs, 3);
  int best = 0;
  double best_inside = -1e300;
  for (int c = 0; c < static_cast<int>(space.cells.size()); ++c) {
    const std::array<double, 3> gc = cell_coordinates(space, space.cells[c], w);
    double inside = gc[0];
    for (int k = 1; k < corners; ++k) inside = std::min(inside, gc[k]);
    if (inside > best_inside) {
      best_inside = inside;
      best = c;
      *g = gc;
      if (inside >= 0) break;
    }
  }
  // Clamp what rounding left slightly negative and keep the coordinates summing to 1.
  double sum = 0;
  for (int k = 0; k < corners; ++k) sum += ((*g)[k] = std::max(0.0, (*g)[k]));
  for (int k = 0; k < corners; ++k) (*g)[k] /= sum;
  return best;
}

// Splits continuous time t in [0, 1] into frame f and fraction alpha towards frame f + 1.
// Positions within 1e-9 of a whole frame snap to it, so t = f / (F - 1) reads frame f alone.
void frame_position(const BlendSpace& space, double t, int* f, double* alpha) {
  const double pos = std::clamp(t, 0.0, 1.0) * (space.num_frames - 1);
  const double whole = std::round(pos);
  *f = std::abs(pos - whole) < 1e-9 ? static_cast<int>(whole) : static_cast<int>(std::floor(pos));
  *alpha = std::abs(pos - whole) < 1e-9 ? 0.0 : pos - *f;
  if (*f >= space.num_frames - 1) {
    *f = space.num_frames - 1;
    *alpha = 0;
  }
}

void add_source(BlendSources* out, const float* frame, double coefficient) {
  if (coefficient == 0) return;  // adding 0 * x changes nothing: skip the read
  assert(out->count < kMaxBlendSources);
  out->sources[out->count] = frame;
  out->coefficients[out->count] = static_cast<float>(coefficient);
  ++out->count;
}

void add_displacement(const BlendSpace& space, BlendSources* out, const std::uint16_t* frame,
                      double coefficient) {
  if (coefficient == 0) return;
  assert(out->displacement_count < kMaxBlendDisplacements);
  out->displacement_sources[out->displacement_count] = frame;
  out->displacement_floats[out->displacement_count] = space.displacement_float(frame);
  out->displacement_coefficients[out->displacement_count] = static_cast<float>(coefficient);
  ++out->displacement_count;
}

// The sources of sum_j g_j M_j(t) over nodes `refs` at frames f and f + 1 (blend.h): the
// inputs with a_k = sum_j g_j w_{j,k}, the other references' displacements with g_j.
void add_time_samples(const BlendSpace& space, std::span<const int> refs, std::span<const double> g,
                      int f, double alpha, BlendSources* out) {
  const int n = space.num_inputs;
  std::array<double, 3> a{};
  out->count = 0;
  out->displacement_count = 0;
  for (std::size_t k = 0; k < refs.size(); ++k) {
    const int r = refs[k];
    if (r < n) {
      a[r] += g[k];  // an input: w_r = e_r, no displacement
      continue;
    }
    for (int i = 0; i < n; ++i) a[i] += g[k] * space.reference_weights[r * n + i];
    add_displacement(space, out, space.displacement(r, f), (1 - alpha) * g[k]);
    if (alpha > 0) add_displacement(space, out, space.displacement(r, f + 1), alpha * g[k]);
  }
  for (int i = 0; i < n; ++i) {
    add_source(out, space.frame(i, f), (1 - alpha) * a[i]);
    if (alpha > 0) add_source(out, space.frame(i, f + 1), alpha * a[i]);
  }
}

// out = sum of K float and H half sources, scaled; K and H are template parameters so the
// loops over sources unroll and the loop over values vectorises (the sources never alias the
// output). The float and the half sums are separate chains (shorter dependencies).
// The displacements as the kernel reads them: the halves, or their decoded floats.
inline const std::uint16_t* displacement_frame(const BlendSources& s, int k, std::uint16_t*) {
  return s.displacement_sources[k];
}
inline const float* displacement_frame(const BlendSources& s, int k, float*) {
  return s.displacement_floats[k];
}
inline float to_float(std::uint16_t h) { return half_to_float(h); }
inline float to_float(float f) { return f; }

template <int K, int H, bool kAccumulate, class D = std::uint16_t>
inline __attribute__((always_inline)) void weighted_sum_body(const BlendSources& s, std::size_t n,
                                                             float* __restrict out) {
  std::array<const float*, std::max(K, 1)> src{};
  std::array<float, std::max(K, 1)> c{};
  std::array<const D*, std::max(H, 1)> dsrc{};
  std::array<float, std::max(H, 1)> dc{};
  for (int k = 0; k < K; ++k) {
    src[k] = s.sources[k];
    c[k] = s.coefficients[k];
  }
  for (int k = 0; k < H; ++k) {
    dsrc[k] = displacement_frame(s, k, static_cast<D*>(nullptr));
    dc[k] = s.displacement_coefficients[k];
  }
#pragma GCC ivdep
  for (std::size_t i = 0; i < n; ++i) {
    float acc = 0, dacc = 0;
    for (int k = 0; k < K; ++k) acc += c[k] * src[k][i];
    for (int k = 0; k < H; ++k) dacc += dc[k] * to_float(dsrc[k][i]);
    if constexpr (H > 0) acc = K > 0 ? acc + dacc : dacc;
    out[i] = kAccumulate ? out[i] + acc : acc;
  }
}

template <int K, int H, bool kAccumulate, class D = std::uint16_t>
void weighted_sum_k(const BlendSources& s, std::size_t n, float* out) {
  weighted_sum_body<K, H, kAccumulate, D>(s, n, out);
}

// The build targets baseline x86-64 (SSE2: 4 floats per instruction, halves converted with
// integer operations). A blend of 12 sources is then bound by load, convert and add throughput
// rather than memory bandwidth, so on CPUs with AVX2, FMA and F16C the kernel also runs
// compiled for them (8 values per instruction, one instruction to convert 8 halves), chosen
// once at run time. Results may differ in the last bit between the two (fused multiply-add
// rounds once).
#if defined(__GNUC__) && defined(__x86_64__)
#define FOURD_BLEND_AVX2 1
template <int K, int H, bool kAccumulate>
__attribute__((target("avx2,fma,f16c"))) void weighted_sum_k_avx2(const BlendSources& s,
                                                                  std::size_t n, float* out) {
  const float* src[std::max(K, 1)]{};
  __m256 c[std::max(K, 1)];
  const std::uint16_t* dsrc[std::max(H, 1)]{};
  __m256 dc[std::max(H, 1)];
  for (int k = 0; k < K; ++k) {
    src[k] = s.sources[k];
    c[k] = _mm256_set1_ps(s.coefficients[k]);
  }
  for (int k = 0; k < H; ++k) {
    dsrc[k] = s.displacement_sources[k];
    dc[k] = _mm256_set1_ps(s.displacement_coefficients[k]);
  }
  std::size_t i = 0;
  for (; i + 8 <= n; i += 8) {
    __m256 acc = _mm256_setzero_ps(), dacc = _mm256_setzero_ps();
    for (int k = 0; k < K; ++k) acc = _mm256_fmadd_ps(c[k], _mm256_loadu_ps(src[k] + i), acc);
    for (int k = 0; k < H; ++k) {
      const __m128i h = _mm_loadu_si128(reinterpret_cast<const __m128i*>(dsrc[k] + i));
      dacc = _mm256_fmadd_ps(dc[k], _mm256_cvtph_ps(h), dacc);
    }
    if constexpr (H > 0) acc = K > 0 ? _mm256_add_ps(acc, dacc) : dacc;
    if constexpr (kAccumulate) acc = _mm256_add_ps(_mm256_loadu_ps(out + i), acc);
    _mm256_storeu_ps(out + i, acc);
  }
  if (i < n) {  // a tail shorter than a vector (frames are whole vectors; only odd callers)
    BlendSources tail = s;
    for (int k = 0; k < K; ++k) tail.sources[k] += i;
    for (int k = 0; k < H; ++k) tail.displacement_sources[k] += i;
    weighted_sum_body<K, H, kAccumulate>(tail, n - i, out + i);
  }
}

#endif

// WebAssembly's 128-bit SIMD (the web build, -msimd128) has no half conversion: converting with
// half_to_float's integer steps costs more than the rest of the sum, so the web build decodes the
// displacements to float once (decode_displacements) and runs this kernel on the floats: 8
// values per iteration (two vectors of 4 floats). It computes exactly what weighted_sum_body
// does (same operations in the same order, no fused multiply-add; half_to_float is exact), so
// its results are those of the generic loop on the halves to the bit.
#if defined(__wasm_simd128__)
#define FOURD_BLEND_WASM_SIMD 1
template <int K, int H, bool kAccumulate>
void weighted_sum_k_simd128(const BlendSources& s, std::size_t n, float* out) {
  const float* src[std::max(K, 1)]{};
  v128_t c[std::max(K, 1)];
  const float* dsrc[std::max(H, 1)]{};
  v128_t dc[std::max(H, 1)];
  for (int k = 0; k < K; ++k) {
    src[k] = s.sources[k];
    c[k] = wasm_f32x4_splat(s.coefficients[k]);
  }
  for (int k = 0; k < H; ++k) {
    dsrc[k] = s.displacement_floats[k];
    dc[k] = wasm_f32x4_splat(s.displacement_coefficients[k]);
  }
  std::size_t i = 0;
  for (; i + 8 <= n; i += 8) {
    v128_t lo = wasm_f32x4_const_splat(0.f), hi = lo, dlo = lo, dhi = lo;
    for (int k = 0; k < K; ++k) {
      lo = wasm_f32x4_add(lo, wasm_f32x4_mul(c[k], wasm_v128_load(src[k] + i)));
      hi = wasm_f32x4_add(hi, wasm_f32x4_mul(c[k], wasm_v128_load(src[k] + i + 4)));
    }
    for (int k = 0; k < H; ++k) {
      dlo = wasm_f32x4_add(dlo, wasm_f32x4_mul(dc[k], wasm_v128_load(dsrc[k] + i)));
      dhi = wasm_f32x4_add(dhi, wasm_f32x4_mul(dc[k], wasm_v128_load(dsrc[k] + i + 4)));
    }
    if constexpr (H > 0) {
      lo = K > 0 ? wasm_f32x4_add(lo, dlo) : dlo;
      hi = K > 0 ? wasm_f32x4_add(hi, dhi) : dhi;
    }
    if constexpr (kAccumulate) {
      lo = wasm_f32x4_add(wasm_v128_load(out + i), lo);
      hi = wasm_f32x4_add(wasm_v128_load(out + i + 4), hi);
    }
    wasm_v128_store(out + i, lo);
    wasm_v128_store(out + i + 4, hi);
  }
  if (i < n) {  // a tail shorter than 8 values (frames are whole vectors; only odd callers)
    BlendSources tail = s;
    for (int k = 0; k < K; ++k) tail.sources[k] += i;
    for (int k = 0; k < H; ++k) tail.displacement_floats[k] += i;
    weighted_sum_body<K, H, kAccumulate, float>(tail, n - i, out + i);
  }
}
#endif

// One kernel per (float count, half count): a table indexed by K * (kMaxBlendDisplacements + 1)
// + H, filled at compile time.
using Kernel = void (*)(const BlendSources&, std::size_t, float*);
constexpr int kHalfCounts = kMaxBlendDisplacements + 1;

template <bool kAccumulate, bool kAvx2, std::size_t... I>
constexpr std::array<Kernel, sizeof...(I)> kernel_table(std::index_sequence<I...>) {
#ifdef FOURD_BLEND_AVX2
  if constexpr (kAvx2) {
    return {{&weighted_sum_k_avx2<static_cast<int>(I) / kHalfCounts,
                                  static_cast<int>(I) % kHalfCounts, kAccumulate>...}};
  }
#endif
  return {{&weighted_sum_k<static_cast<int>(I) / kHalfCounts, static_cast<int>(I) % kHalfCounts,
                           kAccumulate>...}};
}

// The kernels on decoded displacements (BlendSources::decoded).
template <bool kAccumulate, std::size_t... I>
constexpr std::array<Kernel, sizeof...(I)> decoded_kernel_table(std::index_sequence<I...>) {
#ifdef FOURD_BLEND_WASM_SIMD
  return {{&weighted_sum_k_simd128<static_cast<int>(I) / kHalfCounts,
                                   static_cast<int>(I) % kHalfCounts, kAccumulate>...}};
#else
  return {{&weighted_sum_k<static_cast<int>(I) / kHalfCounts, static_cast<int>(I) % kHalfCounts,
                           kAccumulate, float>...}};
#endif
}

template <bool kAccumulate>
void dispatch_weighted_sum(const BlendSources& s, std::size_t n, float* out,
                           bool allow_avx2 = true) {
  assert(s.count >= 0 && s.count <= kMaxBlendSources && s.displacement_count >= 0 &&
         s.displacement_count <= kMaxBlendDisplacements && s.count + s.displacement_count > 0 &&
         "a blend reads 1 to kMaxBlendSources float and 0 to kMaxBlendDisplacements half frames");
  using Indices = std::make_index_sequence<(kMaxBlendSources + 1) * kHalfCounts>;
  const int index = s.count * kHalfCounts + s.displacement_count;
  if (s.decoded()) {
    static constexpr auto kDecoded = decoded_kernel_table<kAccumulate>(Indices{});
    kDecoded[index](s, n, out);
    return;
  }
#ifdef FOURD_BLEND_AVX2
  if (allow_avx2 && cpu_has_avx2_fma_f16c()) {
    static constexpr auto kAvx2 = kernel_table<kAccumulate, true>(Indices{});
    kAvx2[index](s, n, out);
    return;
  }
#endif
  static constexpr auto kBaseline = kernel_table<kAccumulate, false>(Indices{});
  kBaseline[index](s, n, out);
}

// D = m - sum_k w_k input_k at one frame (planes), to fp16; `inputs` points at input 0's
// frame f, input k's is k * F frames further.
void encode_displacement(const BlendSpace& space, int reference, int f, const float* m,
                         const float* inputs, std::uint16_t* out) {
  const int n = space.num_inputs;
  const std::size_t values = space.frame_stride();
  const std::size_t input_stride = static_cast<std::size_t>(space.num_frames) * values;
  const double* w = space.reference_weights.data() + static_cast<std::size_t>(reference) * n;
  for (std::size_t i = 0; i < values; ++i) {
    double linear = 0;
    for (int k = 0; k < n; ++k) linear += w[k] * inputs[k * input_stride + i];
    const float d = static_cast<float>(m[i] - linear);
    if (!(std::abs(d) <= kMaxHalf)) {
      throw InputError(fmt::format(
          "blend space: reference {} frame {}: displacement {} from the linear blend of the inputs "
          "is beyond half precision (|D| <= {}) or not finite",
          reference, f, d, kMaxHalf));
    }
    out[i] = float_to_half(d);
  }
}

}  // namespace

bool cpu_has_avx2_fma_f16c() {
#if defined(__GNUC__) && defined(__x86_64__)
  static const bool yes = [] {
    __builtin_cpu_init();
    // F16C by cpuid (leaf 1, ecx): clang's __builtin_cpu_supports does not know it.
    unsigned eax = 0, ebx = 0, ecx = 0, edx = 0;
    const bool f16c = __get_cpuid(1, &eax, &ebx, &ecx, &edx) && (ecx & bit_F16C) != 0;
    return __builtin_cpu_supports("avx2") && __builtin_cpu_supports("fma") && f16c;
  }();
  return yes;
#else
  return false;
#endif
}

std::uint16_t float_to_half(float x) {
  // After F. Giesen's float_to_half_fast3_rtne: exact round to nearest, ties to even.
  std::uint32_t bits = std::bit_cast<std::uint32_t>(x);
  const std::uint32_t sign = (bits >> 16) & 0x8000u;
  bits &= 0x7fffffffu;
  std::uint32_t h;
  if (bits >= 0x47800000u) {  // >= 2^16 (rounds to infinity), infinity or NaN
    h = bits > 0x7f800000u ? 0x7e00u : 0x7c00u;
  } else if (bits < 0x38800000u) {  // below 2^-14: a subnormal half or zero
    // Adding 0.5 puts the float's last place at 2^-24, the half subnormals' step: the FPU
    // rounds to nearest even, and the low bits are the half's.
    const float shifted = std::bit_cast<float>(bits) + 0.5f;
    h = std::bit_cast<std::uint32_t>(shifted) - 0x3f000000u;
  } else {
    const std::uint32_t odd = (bits >> 13) & 1u;
    bits += (static_cast<std::uint32_t>(15 - 127) << 23) + 0xfffu + odd;  // rebias, round
    h = bits >> 13;  // a carry into the exponent may give infinity (65520 and up): correct
  }
  return static_cast<std::uint16_t>(h | sign);
}

int blend_plane_stride(int num_vertices) {
  // In 64 bits, so a count from a damaged file cannot overflow (the result then fails checks).
  return static_cast<int>((static_cast<std::int64_t>(num_vertices) + kPadFloats - 1) / kPadFloats *
                          kPadFloats);
}

void BlendSpace::check() const {
  if (num_inputs < 1 || num_inputs > 3) {
    throw InputError(fmt::format("blend space: {} inputs (1 to 3 supported)", num_inputs));
  }
  if (num_vertices < 1 || num_frames < 1 || plane_stride != blend_plane_stride(num_vertices)) {
    throw InputError(fmt::format("blend space: bad sizes ({} vertices, {} frames, plane stride {})",
                                 num_vertices, num_frames, plane_stride));
  }
  if (reference_weights.size() % num_inputs != 0 || num_references() < num_inputs) {
    throw InputError(fmt::format("blend space: {} reference weights for {} inputs",
                                 reference_weights.size(), num_inputs));
  }
  const int r = num_references();
  const std::size_t per_reference = static_cast<std::size_t>(num_frames) * frame_stride();
  if (frames.size() != num_inputs * per_reference) {
    throw InputError(
        fmt::format("blend space: {} floats of frames, expected {} inputs x {} "
                    "frames x {}",
                    frames.size(), num_inputs, num_frames, frame_stride()));
  }
  if (displacements.size() != (r - num_inputs) * per_reference) {
    throw InputError(
        fmt::format("blend space: {} halves of displacements, expected {} references "
                    "x {} frames x {}",
                    displacements.size(), r - num_inputs, num_frames, frame_stride()));
  }
  for (int j = 0; j < r; ++j) {
    double sum = 0;
    for (int i = 0; i < num_inputs; ++i) {
      const double wi = reference_weights[j * num_inputs + i];
      if (!(wi >= -kWeightTolerance)) {
        throw InputError(fmt::format("blend space: reference {} has negative weight {}", j, wi));
      }
      if (j < num_inputs && std::abs(wi - (i == j ? 1.0 : 0.0)) > kWeightTolerance) {
        throw InputError(fmt::format("blend space: reference {} must be input {}", j, j));
      }
      sum += wi;
    }
    if (std::abs(sum - 1) > kWeightTolerance) {
      throw InputError(fmt::format("blend space: weights of reference {} sum to {}", j, sum));
    }
  }
  if (cells.empty()) throw InputError("blend space: no cells");
  // The cells must tile the simplex: valid corners and measures adding up to the simplex's.
  double measure = 0;
  for (std::size_t c = 0; c < cells.size(); ++c) {
    const auto& cell = cells[c];
    for (int k = 0; k < 3; ++k) {
      const bool used = k < num_inputs;
      if (used ? (cell[k] < 0 || cell[k] >= r) : cell[k] != -1) {
        throw InputError(fmt::format("blend space: cell {} has bad corner {}", c, cell[k]));
      }
    }
    const double* rw = reference_weights.data();
    if (num_inputs == 2) {
      measure += std::abs(rw[cell[1] * 2 + 1] - rw[cell[0] * 2 + 1]);
    } else if (num_inputs == 3) {
      const double* a = rw + cell[0] * 3;
      const double* b = rw + cell[1] * 3;
      const double* cc = rw + cell[2] * 3;
      measure += 0.5 * std::abs((b[1] - a[1]) * (cc[2] - a[2]) - (cc[1] - a[1]) * (b[2] - a[2]));
    }
  }
  if (!cell_arc_angles.empty()) {
    if (cell_arc_angles.size() != cells.size()) {
      throw InputError(fmt::format("blend space: {} arc angles for {} cells",
                                   cell_arc_angles.size(), cells.size()));
    }
    for (std::size_t c = 0; c < cells.size(); ++c) {
      const double a = cell_arc_angles[c];
      if (!(a >= 0 && a <= std::numbers::pi) || (num_inputs != 2 && a != 0)) {
        throw InputError(fmt::format("blend space: cell {} has arc angle {} (0 to pi, segments only)",
                                     c, a));
      }
    }
  }
  const double expected = num_inputs == 1 ? 0.0 : num_inputs == 2 ? 1.0 : 0.5;
  if (std::abs(measure - expected) > 1e-9) {
    throw InputError(fmt::format("blend space: cells cover {} of the weight simplex, expected {}",
                                 measure, expected));
  }
}

BlendSpace make_blend_space(int num_inputs, int num_vertices, int num_frames) {
  if (num_inputs < 1 || num_inputs > 3 || num_vertices < 1 || num_frames < 1) {
    throw InputError(
        fmt::format("blend space: unsupported sizes ({} inputs, {} vertices, {} frames)",
                    num_inputs, num_vertices, num_frames));
  }
  BlendSpace space;
  space.num_inputs = num_inputs;
  space.num_vertices = num_vertices;
  space.num_frames = num_frames;
  space.plane_stride = blend_plane_stride(num_vertices);
  space.reference_weights.assign(static_cast<std::size_t>(num_inputs) * num_inputs, 0.0);
  for (int i = 0; i < num_inputs; ++i) space.reference_weights[i * num_inputs + i] = 1.0;
  space.frames.assign(static_cast<std::size_t>(num_inputs) * num_frames * space.frame_stride(),
                      0.f);
  space.cells.push_back({0, num_inputs > 1 ? 1 : -1, num_inputs > 2 ? 2 : -1});
  return space;
}

int add_reference(BlendSpace* space, std::span<const double> w) {
  if (static_cast<int>(w.size()) != space->num_inputs) {
    throw InputError(fmt::format("blend space: reference with {} weights for {} inputs", w.size(),
                                 space->num_inputs));
  }
  space->reference_weights.insert(space->reference_weights.end(), w.begin(), w.end());
  space->displacements.resize(
      space->displacements.size() + space->num_frames * space->frame_stride(), 0);
  return space->num_references() - 1;
}

void truncate_references(BlendSpace* space, int count) {
  assert(count >= space->num_inputs && count <= space->num_references());
  space->reference_weights.resize(static_cast<std::size_t>(count) * space->num_inputs);
  space->displacements.resize(static_cast<std::size_t>(count - space->num_inputs) *
                              space->num_frames * space->frame_stride());
}

void set_frame(BlendSpace* space, int reference, int f, std::span<const Vec3f> positions) {
  if (static_cast<int>(positions.size()) != space->num_vertices || reference < 0 ||
      reference >= space->num_references() || f < 0 || f >= space->num_frames) {
    throw InputError(
        fmt::format("blend space: cannot set frame {} of reference {} from {} positions", f,
                    reference, positions.size()));
  }
  if (reference < space->num_inputs && space->num_references() > space->num_inputs) {
    throw InputError(fmt::format(
        "blend space: cannot set frame {} of input {} after references were added (their "
        "displacements are relative to the inputs: set every input frame first)",
        f, reference));
  }
  const std::size_t stride = space->plane_stride;
  auto scatter = [&](float* dst) {
    for (std::size_t v = 0; v < positions.size(); ++v) {
      dst[v] = positions[v].x();
      dst[stride + v] = positions[v].y();
      dst[2 * stride + v] = positions[v].z();
    }
  };
  if (reference < space->num_inputs) {
    scatter(space->frame(reference, f));
    return;
  }
  std::vector<float> mesh(space->frame_stride(), 0.f);
  scatter(mesh.data());
  encode_displacement(*space, reference, f, mesh.data(), space->frame(0, f),
                      space->displacement(reference, f));
}

void reference_frame(const BlendSpace& space, int reference, int f, float* out) {
  assert(reference >= 0 && reference < space.num_references() && f >= 0 && f < space.num_frames);
  const std::size_t values = space.frame_stride();
  if (reference < space.num_inputs) {
    std::copy_n(space.frame(reference, f), values, out);
    return;
  }
  const int n = space.num_inputs;
  const double* w = space.reference_weights.data() + static_cast<std::size_t>(reference) * n;
  const std::uint16_t* d = space.displacement(reference, f);
  for (std::size_t i = 0; i < values; ++i) {
    double x = half_to_float(d[i]);
    for (int k = 0; k < n; ++k) x += w[k] * space.frame(k, f)[i];
    out[i] = static_cast<float>(x);
  }
}

void split_reference_frames(const BlendSpace& space, std::span<const float> all,
                            AlignedFloats* inputs, AlignedHalfs* displacements) {
  const int n = space.num_inputs;
  if (n < 1 || n > 3 || space.num_vertices < 1 || space.num_frames < 1 ||
      space.plane_stride != blend_plane_stride(space.num_vertices) ||
      space.reference_weights.size() % n != 0 || space.num_references() < n) {
    throw InputError(
        fmt::format("blend space: bad sizes ({} inputs, {} vertices, {} frames, "
                    "plane stride {}, {} reference weights)",
                    n, space.num_vertices, space.num_frames, space.plane_stride,
                    space.reference_weights.size()));
  }
  const std::size_t per_reference =
      static_cast<std::size_t>(space.num_frames) * space.frame_stride();
  const int r = space.num_references();
  if (all.size() % per_reference != 0 ||
      all.size() / per_reference != static_cast<std::size_t>(r)) {
    throw InputError(
        fmt::format("blend space: {} floats of reference frames, expected {} "
                    "references x {} frames x {}",
                    all.size(), r, space.num_frames, space.frame_stride()));
  }
  inputs->assign(all.begin(), all.begin() + n * per_reference);
  displacements->assign((r - n) * per_reference, 0);
  for (int j = n; j < r; ++j) {
    for (int f = 0; f < space.num_frames; ++f) {
      const std::size_t at = static_cast<std::size_t>(f) * space.frame_stride();
      encode_displacement(space, j, f, all.data() + j * per_reference + at, all.data() + at,
                          displacements->data() + (j - n) * per_reference + at);
    }
  }
}

void decode_displacements(const AlignedHalfs& halves, AlignedFloats* floats) {
  floats->resize(halves.size());
  for (std::size_t i = 0; i < halves.size(); ++i) (*floats)[i] = half_to_float(halves[i]);
}

BlendedFrame make_blended_frame(const BlendSpace& space) {
  BlendedFrame frame;
  frame.num_vertices = space.num_vertices;
  frame.plane_stride = space.plane_stride;
  frame.data.assign(space.frame_stride(), 0.f);
  return frame;
}

void copy_positions(const BlendedFrame& frame, std::vector<Vec3f>* positions) {
  positions->resize(frame.num_vertices);
  for (int v = 0; v < frame.num_vertices; ++v) (*positions)[v] = frame.position(v);
}

int find_reference(const BlendSpace& space, std::span<const double> w) {
  const int n = space.num_inputs;
  const int r = space.num_references();
  const double* rw = space.reference_weights.data();
  for (int j = 0; j < r; ++j) {
    bool same = true;
    for (int i = 0; i < n && same; ++i) same = std::abs(rw[j * n + i] - w[i]) <= 1e-9;
    if (same) return j;
  }
  return -1;
}

std::array<int, 3> cell_midpoints(const BlendSpace& space, const std::array<int, 3>& cell) {
  std::array<int, 3> mids{-1, -1, -1};
  const int n = space.num_inputs;
  if (n < 2) return mids;
  const double* rw = space.reference_weights.data();
  auto mid = [&](int a, int b) {
    std::array<double, 3> m{};
    for (int i = 0; i < n; ++i) m[i] = 0.5 * (rw[a * n + i] + rw[b * n + i]);
    return find_reference(space, std::span<const double>(m.data(), n));
  };
  if (n == 2) {
    mids[0] = mid(cell[0], cell[1]);
  } else {
    for (int k = 0; k < 3; ++k) mids[k] = mid(cell[(k + 1) % 3], cell[(k + 2) % 3]);
  }
  return mids;
}

void cell_shape_functions(const BlendSpace& space, const std::array<int, 3>& cell,
                          const std::array<int, 3>& midpoints, const std::array<double, 3>& lambda,
                          double arc_angle, CellNodes* out) {
  const int corners = space.num_inputs;
  std::array<double, 3> gc{}, gm{};
  // P2 Lagrange basis: corner k: lambda_k (2 lambda_k - 1); midpoint opposite corner k (the
  // edge between the two others; for a segment the only edge): 4 lambda_i lambda_j.
  for (int k = 0; k < corners; ++k) gc[k] = corners == 1 ? 1.0 : lambda[k] * (2 * lambda[k] - 1);
  if (corners == 2 && midpoints[0] >= 0 && arc_angle > kMinArcAngle) {
    // Trigonometric Lagrange basis on nodes 0, theta / 2, theta (blend.h).
    const double theta = arc_angle, phi = theta * lambda[1];
    const double q = std::sin(0.25 * theta), h = std::sin(0.5 * theta);
    const double s0 = std::sin(0.5 * phi), s1 = std::sin(0.5 * phi - 0.25 * theta),
                 s2 = std::sin(0.5 * phi - 0.5 * theta);
    gc[0] = s1 * s2 / (q * h);
    gm[0] = -s0 * s2 / (q * q);
    gc[1] = s0 * s1 / (h * q);
  } else if (corners == 2) {
    gm[0] = 4 * lambda[0] * lambda[1];
  } else if (corners == 3) {
    for (int k = 0; k < 3; ++k) gm[k] = 4 * lambda[(k + 1) % 3] * lambda[(k + 2) % 3];
  }
  // A missing midpoint node: the edge is linear, its value the mean of the two ends.
  const int edges = corners == 3 ? 3 : corners - 1;
  for (int k = 0; k < edges; ++k) {
    if (midpoints[k] >= 0) continue;
    const int a = corners == 2 ? 0 : (k + 1) % 3, b = corners == 2 ? 1 : (k + 2) % 3;
    gc[a] += 0.5 * gm[k];
    gc[b] += 0.5 * gm[k];
    gm[k] = 0;
  }
  out->count = 0;
  auto add = [&](int reference, double g) {
    if (g == 0) return;
    out->references[out->count] = reference;
    out->g[out->count] = g;
    ++out->count;
  };
  for (int k = 0; k < corners; ++k) add(cell[k], gc[k]);
  for (int k = 0; k < edges; ++k) add(midpoints[k], gm[k]);
}

void hybrid_blend_sources(const BlendSpace& space, double t, std::span<const float> w,
                          BlendSources* out) {
  std::array<double, 3> p{}, lambda{};
  normalised_weights(w, space.num_inputs, &p);
  CellNodes nodes;
  const int c = locate_cell(space, p, &lambda);
  cell_shape_functions(space, space.cells[c], cell_midpoints(space, space.cells[c]), lambda,
                       space.cell_arc_angle(c), &nodes);
  int f = 0;
  double alpha = 0;
  frame_position(space, t, &f, &alpha);
  add_time_samples(space, std::span<const int>(nodes.references.data(), nodes.count),
                   std::span<const double>(nodes.g.data(), nodes.count), f, alpha, out);
}

void linear_blend_sources(const BlendSpace& space, double t, std::span<const float> w,
                          BlendSources* out) {
  std::array<double, 3> p{};
  normalised_weights(w, space.num_inputs, &p);
  int f = 0;
  double alpha = 0;
  frame_position(space, t, &f, &alpha);
  static constexpr std::array<int, 3> kInputs{0, 1, 2};
  add_time_samples(space, std::span<const int>(kInputs.data(), space.num_inputs),
                   std::span<const double>(p.data(), space.num_inputs), f, alpha, out);
}

void weighted_sum(const BlendSources& s, std::size_t n, float* out) {
  dispatch_weighted_sum<false>(s, n, out);
}

void accumulate_weighted_sum(const BlendSources& s, std::size_t n, float* out) {
  dispatch_weighted_sum<true>(s, n, out);
}

void portable_weighted_sum(const BlendSources& s, std::size_t n, bool accumulate, float* out) {
  if (accumulate) {
    dispatch_weighted_sum<true>(s, n, out, false);
  } else {
    dispatch_weighted_sum<false>(s, n, out, false);
  }
}

void blend_hybrid(const BlendSpace& space, double t, std::span<const float> w, BlendedFrame* out) {
  assert(out->plane_stride == space.plane_stride && out->data.size() == space.frame_stride());
  BlendSources sources;
  hybrid_blend_sources(space, t, w, &sources);
  weighted_sum(sources, space.frame_stride(), out->data.data());
}

void blend_linear(const BlendSpace& space, double t, std::span<const float> w, BlendedFrame* out) {
  assert(out->plane_stride == space.plane_stride && out->data.size() == space.frame_stride());
  BlendSources sources;
  linear_blend_sources(space, t, w, &sources);
  weighted_sum(sources, space.frame_stride(), out->data.data());
}

}  // namespace fourd
