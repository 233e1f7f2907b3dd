// Motion-space blending on one core: the runtime's hybrid (Eq. 1) and linear blends at
// continuous (t, w), a memory-bound baseline that reads exactly what the hybrid reads, and the
// offline non-linear blend (precompute / prepare / solve). Meshes: closed tubes of about 3k,
// 10k and 50k vertices; 3 inputs of 40 frames each (the *Line benchmarks: 2 inputs).
#include <benchmark/benchmark.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <map>
#include <numbers>
#include <random>
#include <utility>
#include <vector>

#if defined(__GNUC__) && defined(__x86_64__)
#include <immintrin.h>
#endif

#include "runtime/blend.h"
#include "stages/motionspace/nonlinear_blend.h"
#include "tests/motionspace/test_meshes.h"

namespace fourd {
namespace {

constexpr int kFrames = 40;
constexpr double kDeg = std::numbers::pi / 180;

// rings x segments + 2 cap vertices: 3002, 10002, 50002.
test::TestMesh tube_of_size(int vertices) {
  if (vertices <= 3002) return test::make_tube(100, 30);
  if (vertices <= 10002) return test::make_tube(200, 50);
  return test::make_tube(500, 100);
}

Eigen::Matrix3Xd input_pose(const test::TestMesh& m, int k, int f) {
  return test::bend_tube(m.positions, (10.0 + 30 * k + f) * kDeg, {}, 40.0 * k * kDeg);
}

// A 3-input space with the three edge-midpoint references and one quadratic (6-node P2) cell
// over the whole weight triangle: what a build gives before any bisection. An evaluation reads
// the 3 inputs' float frames and the 3 midpoints' fp16 displacements at 2 time samples (a cell
// of a deeper build, whose corners are references too, reads up to 6 displacements x 2).
// Reference frames are the linear blends plus a bend, so the values are realistic; the
// runtime's cost does not depend on them.
struct BenchSpace {
  test::TestMesh mesh;
  BlendSpace space;
};

// inputs = 3: the P2 triangle above. inputs = 2 (the "Line" benchmarks, the layout of Table 1's
// "hybrid, 1 reference"): inputs 0 and 1 with the reference at w = 1/2, one arc segment (3 nodes
// x 2 time samples).
const BenchSpace& bench_space(int vertices, int inputs = 3) {
  static std::map<std::pair<int, int>, BenchSpace> cache;
  auto it = cache.find({vertices, inputs});
  if (it != cache.end()) return it->second;
  BenchSpace b;
  b.mesh = tube_of_size(vertices);
  b.space = make_blend_space(inputs, static_cast<int>(b.mesh.positions.cols()), kFrames);
  for (int k = 0; k < inputs; ++k) {
    for (int f = 0; f < kFrames; ++f)
      set_frame(&b.space, k, f, test::to_vec3f(input_pose(b.mesh, k, f)));
  }
  std::vector<std::array<double, 3>> mids{{0.5, 0.5, 0}, {0, 0.5, 0.5}, {0.5, 0, 0.5}};
  if (inputs == 2) mids.resize(1);
  std::vector<int> r;
  for (const auto& mid : mids) {
    r.push_back(add_reference(&b.space, std::span<const double>(mid.data(), inputs)));
    for (int f = 0; f < kFrames; ++f) {
      Eigen::Matrix3Xd x = Eigen::Matrix3Xd::Zero(3, b.mesh.positions.cols());
      for (int k = 0; k < inputs; ++k) x += mid[k] * input_pose(b.mesh, k, f);
      set_frame(&b.space, r.back(), f, test::to_vec3f(test::bend_tube(x, 5 * kDeg)));
    }
  }
  b.space.cells = {{0, 1, inputs == 3 ? 2 : -1}};
  if (inputs == 2) b.space.cell_arc_angles = {1.8};  // the arc basis (its sines are timed too)
  b.space.check();
  const std::array<int, 3> expected =
      inputs == 3 ? std::array<int, 3>{r[1], r[2], r[0]} : std::array<int, 3>{r[0], -1, -1};
  if (cell_midpoints(b.space, b.space.cells[0]) != expected) {
    std::abort();  // the cell would not be quadratic: the benchmark would measure the wrong thing
  }
  return cache.emplace(std::make_pair(vertices, inputs), std::move(b)).first->second;
}

// A fixed pseudo-random walk over (t, w): time jumps across frames (so frames come from L3 or
// memory, not L1), weights anywhere in the triangle.
struct Query {
  double t;
  std::array<float, 3> w;
};
std::vector<Query> queries() {
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> u(0.f, 1.f);
  std::vector<Query> q(1024);
  double t = 0;
  for (auto& x : q) {
    t = std::fmod(t + 0.618034, 1.0);
    x.t = t;
    const float a = u(rng), b = u(rng);
    x.w = a + b <= 1 ? std::array<float, 3>{a, b, 1 - a - b}
                     : std::array<float, 3>{1 - a, 1 - b, a + b - 1};
  }
  return q;
}

std::size_t read_bytes(const BlendSources& s, std::size_t values) {
  return s.read_bytes(values) + values * sizeof(float);  // sources read + output written
}

void run_hybrid(benchmark::State& state, int inputs) {
  const BlendSpace& space = bench_space(static_cast<int>(state.range(0)), inputs).space;
  const std::vector<Query> q = queries();
  std::vector<std::size_t> query_bytes(q.size());
  for (std::size_t i = 0; i < q.size(); ++i) {
    BlendSources s;
    hybrid_blend_sources(space, q[i].t, q[i].w, &s);
    query_bytes[i] = read_bytes(s, space.frame_stride());
  }
  BlendedFrame out = make_blended_frame(space);
  std::size_t i = 0, bytes = 0;
  for (auto _ : state) {
    const std::size_t k = i++ & 1023;
    blend_hybrid(space, q[k].t, q[k].w, &out);
    benchmark::DoNotOptimize(out.data.data());
    benchmark::ClobberMemory();
    bytes += query_bytes[k];
  }
  state.SetBytesProcessed(static_cast<int64_t>(bytes));
  state.counters["vertices"] = space.num_vertices;
}
void BM_HybridBlend(benchmark::State& state) { run_hybrid(state, 3); }
void BM_HybridBlendLine(benchmark::State& state) { run_hybrid(state, 2); }

// The same evaluation at one (t, w) over and over: the frames stay in L1/L2.
void BM_HybridBlendHot(benchmark::State& state) {
  const BlendSpace& space = bench_space(static_cast<int>(state.range(0))).space;
  BlendedFrame out = make_blended_frame(space);
  const std::array<float, 3> w{0.3f, 0.3f, 0.4f};
  BlendSources s;
  hybrid_blend_sources(space, 0.51, w, &s);
  for (auto _ : state) {
    blend_hybrid(space, 0.51, w, &out);
    benchmark::DoNotOptimize(out.data.data());
    benchmark::ClobberMemory();
  }
  state.SetBytesProcessed(
      static_cast<int64_t>(state.iterations() * read_bytes(s, space.frame_stride())));
}

// Baseline: reads the very frames each hybrid evaluation reads (precomputed lists: the inputs'
// float frames and the references' fp16 displacements) once, converts the halves and writes
// the plain sum; no cell lookup, no coefficients. The floor for a memory-bound blend. Compiled
// like runtime/blend.cpp's kernel: for the baseline x86-64 (halves converted by
// half_to_float) and, dispatched at run time, for AVX2 + FMA + F16C.
template <int K, int H>
inline __attribute__((always_inline)) void plain_sum_body(const BlendSources& s, std::size_t n,
                                                          float* __restrict out) {
  const float* src[std::max(K, 1)]{};
  const std::uint16_t* dsrc[std::max(H, 1)]{};
  for (int k = 0; k < K; ++k) src[k] = s.sources[k];
  for (int k = 0; k < H; ++k) dsrc[k] = s.displacement_sources[k];
#pragma GCC ivdep
  for (std::size_t i = 0; i < n; ++i) {
    float acc = 0;
    for (int k = 0; k < K; ++k) acc += src[k][i];
    for (int k = 0; k < H; ++k) acc += half_to_float(dsrc[k][i]);
    out[i] = acc;
  }
}

#if defined(__GNUC__) && defined(__x86_64__)
// Frames are whole vectors of 8 values (3 planes of a multiple of 16).
template <int K, int H>
__attribute__((target("avx2,fma,f16c"))) void plain_sum_avx2(const BlendSources& s, std::size_t n,
                                                             float* out) {
  for (std::size_t i = 0; i + 8 <= n; i += 8) {
    __m256 acc = _mm256_setzero_ps();
    for (int k = 0; k < K; ++k) acc = _mm256_add_ps(acc, _mm256_loadu_ps(s.sources[k] + i));
    for (int k = 0; k < H; ++k) {
      const __m128i h =
          _mm_loadu_si128(reinterpret_cast<const __m128i*>(s.displacement_sources[k] + i));
      acc = _mm256_add_ps(acc, _mm256_cvtph_ps(h));
    }
    _mm256_storeu_ps(out + i, acc);
  }
}
#endif

template <int K, int H>
void plain_sum(const BlendSources& s, std::size_t n, float* out) {
#if defined(__GNUC__) && defined(__x86_64__)
  if (cpu_has_avx2_fma_f16c()) return plain_sum_avx2<K, H>(s, n, out);
#endif
  plain_sum_body<K, H>(s, n, out);
}

template <int K, int... H>
bool plain_sum_halves(const BlendSources& s, std::size_t n, float* out,
                      std::integer_sequence<int, H...>) {
  return ((s.displacement_count == H ? (plain_sum<K, H>(s, n, out), true) : false) || ...);
}

template <int... K>
void baseline_dispatch(const BlendSources& s, std::size_t n, float* out,
                       std::integer_sequence<int, K...>) {
  using Halves = std::make_integer_sequence<int, kMaxBlendDisplacements + 1>;
  ((s.count == K ? plain_sum_halves<K>(s, n, out, Halves{}) : false) || ...);
}

void baseline(const BlendSources& s, std::size_t n, float* out) {
  baseline_dispatch(s, n, out, std::make_integer_sequence<int, kMaxBlendSources + 1>{});
}

void run_baseline(benchmark::State& state, bool hot, int inputs = 3) {
  const BlendSpace& space = bench_space(static_cast<int>(state.range(0)), inputs).space;
  const std::vector<Query> q = queries();
  std::vector<BlendSources> sources(q.size());
  for (std::size_t i = 0; i < q.size(); ++i) {
    hybrid_blend_sources(space, hot ? 0.51 : q[i].t,
                         hot ? std::array<float, 3>{0.3f, 0.3f, 0.4f} : q[i].w, &sources[i]);
  }
  BlendedFrame out = make_blended_frame(space);
  std::size_t i = 0, bytes = 0;
  for (auto _ : state) {
    const BlendSources& s = sources[i++ & 1023];
    baseline(s, space.frame_stride(), out.data.data());
    benchmark::DoNotOptimize(out.data.data());
    benchmark::ClobberMemory();
    bytes += read_bytes(s, space.frame_stride());
  }
  state.SetBytesProcessed(static_cast<int64_t>(bytes));
}
void BM_BaselineRead(benchmark::State& state) { run_baseline(state, false); }
void BM_BaselineReadHot(benchmark::State& state) { run_baseline(state, true); }
void BM_BaselineReadLine(benchmark::State& state) { run_baseline(state, false, 2); }

void run_linear(benchmark::State& state, int inputs) {
  const BlendSpace& space = bench_space(static_cast<int>(state.range(0)), inputs).space;
  const std::vector<Query> q = queries();
  BlendedFrame out = make_blended_frame(space);
  std::size_t i = 0;
  for (auto _ : state) {
    const Query& x = q[i++ & 1023];
    blend_linear(space, x.t, x.w, &out);
    benchmark::DoNotOptimize(out.data.data());
    benchmark::ClobberMemory();
  }
}
void BM_LinearBlend(benchmark::State& state) { run_linear(state, 3); }
void BM_LinearBlendLine(benchmark::State& state) { run_linear(state, 2); }

// Offline non-linear blend, 3 inputs: factorisation once per topology, decomposition once per
// frame, and the per-weight solve (rotation/stretch blend + right-hand side + back-substitution).
struct NonlinearSetup {
  test::TestMesh mesh;
  std::vector<Eigen::Matrix3Xd> inputs;
  NonlinearBlendData data;
  NonlinearBlendInputs prepared;
};
const NonlinearSetup& nonlinear_setup(int vertices) {
  static std::map<int, NonlinearSetup> cache;
  auto it = cache.find(vertices);
  if (it != cache.end()) return it->second;
  NonlinearSetup& s = cache[vertices];
  s.mesh = tube_of_size(vertices);
  for (int k = 0; k < 3; ++k) s.inputs.push_back(input_pose(s.mesh, k, 10));
  nonlinear_blend_precompute(s.mesh.positions, s.mesh.triangles, &s.data);
  nonlinear_blend_prepare(s.data, s.inputs, &s.prepared);
  return s;
}

void BM_NonlinearSolve(benchmark::State& state) {
  const NonlinearSetup& s = nonlinear_setup(static_cast<int>(state.range(0)));
  Eigen::Matrix3Xd out;
  const std::vector<double> w{0.2, 0.5, 0.3};
  for (auto _ : state) {
    nonlinear_blend_solve(s.data, s.prepared, w, &out);
    benchmark::DoNotOptimize(out.data());
  }
  state.counters["vertices"] = static_cast<double>(s.mesh.positions.cols());
  state.counters["factor_nnz"] =
      static_cast<double>(s.data.solver->matrixL().nestedExpression().nonZeros());
}

void BM_NonlinearPrepare(benchmark::State& state) {
  const NonlinearSetup& s = nonlinear_setup(static_cast<int>(state.range(0)));
  NonlinearBlendInputs prepared;
  for (auto _ : state) {
    nonlinear_blend_prepare(s.data, s.inputs, &prepared);
    benchmark::DoNotOptimize(prepared.stretches.data());
  }
}

void BM_NonlinearPrecompute(benchmark::State& state) {
  const NonlinearSetup& s = nonlinear_setup(static_cast<int>(state.range(0)));
  for (auto _ : state) {
    NonlinearBlendData data;
    nonlinear_blend_precompute(s.mesh.positions, s.mesh.triangles, &data);
    benchmark::DoNotOptimize(data.solver.get());
  }
}

BENCHMARK(BM_HybridBlend)->Arg(3000)->Arg(10000)->Arg(50000)->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_BaselineRead)->Arg(3000)->Arg(10000)->Arg(50000)->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_HybridBlendHot)->Arg(3000)->Arg(10000)->Arg(50000)->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_BaselineReadHot)->Arg(3000)->Arg(10000)->Arg(50000)->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_LinearBlend)->Arg(3000)->Arg(10000)->Arg(50000)->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_HybridBlendLine)->Arg(3000)->Arg(10000)->Arg(50000)->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_BaselineReadLine)->Arg(3000)->Arg(10000)->Arg(50000)->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_LinearBlendLine)->Arg(3000)->Arg(10000)->Arg(50000)->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_NonlinearSolve)->Arg(3000)->Arg(10000)->Arg(50000)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_NonlinearPrepare)->Arg(3000)->Arg(10000)->Arg(50000)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_NonlinearPrecompute)->Arg(3000)->Arg(10000)->Arg(50000)->Unit(benchmark::kMillisecond);

}  // namespace
}  // namespace fourd
