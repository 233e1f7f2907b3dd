// One runtime step (runtime/character.h): the ticks of motion time (parameter ramp, root
// integration, bookkeeping) plus the hybrid blend of positions AND normals with the same
// coefficients, and normal normalisation; for characters of about 3k, 10k and 50k vertices.
//
// Compare with BM_BaselineRead / BM_BaselineReadHot of blend_bench.cpp (the memory-bound
// floor: read the frames one hybrid blend reads, write one frame), which run in the same
// fourd_bench program:
//   fourd_bench --benchmark_filter='BM_RuntimeStep|BM_BaselineRead'
// A step reads and writes twice what one blend does (positions and normals), so its floor is
// about 2 x BM_BaselineRead(Hot).
//
// The motion space is built like blend_bench's: 3 inputs of 40 frames, the three edge-midpoint
// references and 4 cells; normals are a second array of the same layout (values do not change
// the cost). The character walks at 60 Hz while its parameter sweeps the range, so the frames
// read change from step to step as in real play. BM_RuntimeStep/16 (a 14-vertex tube) is the
// per-step bookkeeping alone: ticks, weights, root, cell lookup.
//
// Measured 2026-11-23 (2-core shared VM, Release, CPU time; one run of
// `fourd_bench --benchmark_filter='BM_RuntimeStep|BM_BaselineRead'`):
//   vertices                 14      3,002    10,002    50,002
//   BM_RuntimeStep        0.65 us    4.9 us   20.1 us   113 us   (205k / 50k / 8.9k steps/s)
//   BM_RuntimeStepRawNormals         3.6 us   12.4 us    91 us   (no normalisation pass)
//   BM_RuntimeStepCrossfade         14.0 us   56.6 us   381 us   (during a cross-fade only)
//   BM_BaselineRead                  5.0 us   24.8 us   212 us   (one blend's reads, cold)
//   BM_BaselineReadHot               2.1 us   14.3 us    76 us   (one blend's reads, cached)
// Step / BaselineRead: 0.97, 0.81, 0.53; step / BaselineReadHot: 2.3, 1.4, 1.5 (a step blends
// positions and normals, i.e. two blends, and normalises the normals).
#include <benchmark/benchmark.h>

#include <cmath>
#include <map>
#include <memory>
#include <numbers>
#include <span>

#include "runtime/character.h"
#include "runtime/transition.h"
#include "tests/motionspace/test_meshes.h"

namespace fourd {
namespace {

constexpr int kFrames = 40;
constexpr double kDeg = std::numbers::pi / 180;

test::TestMesh tube(int vertices) {
  if (vertices <= 16) return test::make_tube(3, 4);  // 14 vertices: the bookkeeping alone
  if (vertices <= 3002) return test::make_tube(100, 30);
  if (vertices <= 10002) return test::make_tube(200, 50);
  return test::make_tube(500, 100);
}

// A one-space graph (cyclic locomotion, 3 inputs, self-loop) of about `vertices` vertices.
// p2: the three references are the midpoints of one quadratic (P2) cell, as hybrid_build makes
// them; else 4 linear cells split at them.
const MotionGraph& bench_graph(int vertices, bool p2 = false) {
  static std::map<std::pair<int, bool>, std::unique_ptr<MotionGraph>> cache;
  auto it = cache.find({vertices, p2});
  if (it != cache.end()) return *it->second;
  const test::TestMesh mesh = tube(vertices);
  const int nv = static_cast<int>(mesh.positions.cols());
  auto pose = [&](const std::array<double, 3>& w, int f) {
    Eigen::Matrix3Xd x = Eigen::Matrix3Xd::Zero(3, nv);
    const double phase = std::sin(2 * std::numbers::pi * f / (kFrames - 1));
    for (int k = 0; k < 3; ++k) {
      if (w[k] > 0) x += w[k] * test::bend_tube(mesh.positions, (10.0 + 30 * k) * phase * kDeg, {},
                                                 40.0 * k * kDeg);
    }
    return x;
  };
  MotionSpace s;
  s.name = "locomotion";
  s.cyclic = true;
  s.takes = {"a", "b", "c"};
  s.character_height = 1.0;
  s.triangles = mesh.triangles;
  s.blend = make_blend_space(3, nv, kFrames);
  const std::array<std::array<double, 3>, 6> refs{
      {{1, 0, 0}, {0, 1, 0}, {0, 0, 1}, {0.5, 0.5, 0}, {0, 0.5, 0.5}, {0.5, 0, 0.5}}};
  for (int j = 0; j < 6; ++j) {  // inputs first: the references are stored relative to them
    if (j >= 3) add_reference(&s.blend, refs[j]);
    for (int f = 0; f < kFrames; ++f) set_frame(&s.blend, j, f, test::to_vec3f(pose(refs[j], f)));
  }
  s.blend.cells = {{0, 3, 5}, {3, 1, 4}, {5, 4, 2}, {3, 4, 5}};
  if (p2) s.blend.cells = {{0, 1, 2}};
  for (int k = 0; k < 3; ++k) {
    for (int f = 0; f < kFrames; ++f) {
      const double t = static_cast<double>(f) / (kFrames - 1);
      s.roots.push_back({static_cast<float>((1.0 + 0.3 * k) * t), 0.f, 0.f});
      s.seconds.push_back(static_cast<float>((1.0 - 0.1 * k) * t));
    }
  }
  s.parameter_map = {"speed", "m/s", 3, {0, 1, 2}, {1.0, 1.3, 1.6}};
  auto g = std::make_unique<MotionGraph>();
  g->name = "bench";
  g->fps = 25;
  GraphSpace gs;
  gs.motion = std::move(s);
  gs.normals = gs.motion.blend.frames;  // same layout; the values do not matter here
  gs.normal_displacements = gs.motion.blend.displacements;
  g->spaces.push_back(std::move(gs));
  GraphEdge loop;
  loop.from = loop.to = 0;
  loop.self_loop = true;
  EdgeSimilarity& sim = loop.similarity;
  sim.source_inputs = sim.target_inputs = 3;
  sim.source_samples = sim.target_samples = kFrames;
  sim.max_distance = 1;
  sim.values.resize(static_cast<std::size_t>(kFrames) * kFrames * 9);
  for (std::size_t i = 0; i < sim.values.size(); ++i) sim.values[i] = 0.5f + 0.4f * std::sin(0.37 * i);
  g->edges.push_back(std::move(loop));
  g->check();
  return *cache.emplace(std::make_pair(vertices, p2), std::move(g)).first->second;
}

// Bytes a step reads and writes in its blends (positions and normals: every source frame read
// once, the output written once), averaged over `steps` steps of the same deterministic run, so
// that bytes_per_second compares with BM_BaselineRead's.
double bytes_per_step(const MotionGraph& g, int steps) {
  Character c(g, TransitionOptions{});
  c.reset(0, 1.0);
  const GraphSpace& space = g.spaces.front();
  double bytes = 0;
  for (int k = 0; k < steps; ++k) {
    if ((k & 127) == 0) c.set_parameters(((k + 1) & 256) ? 1.0 : 1.6);
    c.step(1.0 / 60);
    std::array<float, 3> w{};
    space_weights(space, c.state().p, &w);
    BlendSources s;
    hybrid_blend_sources(space.motion.blend, c.state().t, std::span<const float>(w.data(), 3), &s);
    const std::size_t values = space.motion.blend.frame_stride();
    bytes += 2.0 * (s.read_bytes(values) + values * sizeof(float));  // + the output written
  }
  return bytes / steps;
}

void run_step(benchmark::State& state, bool normalize, bool p2 = false) {
  const MotionGraph& g = bench_graph(static_cast<int>(state.range(0)), p2);
  CharacterOptions o;
  o.normalize_normals = normalize;
  Character c(g, TransitionOptions{}, o);
  c.reset(0, 1.0);
  int k = 0;
  for (auto _ : state) {
    // Sweep the parameter now and then so the weights (and the cells read) keep changing.
    if ((k & 127) == 0) c.set_parameters(((k + 1) & 256) ? 1.0 : 1.6);
    ++k;
    const CharacterFrame& f = c.step(1.0 / 60);
    benchmark::DoNotOptimize(f.positions.data.data());
    benchmark::DoNotOptimize(f.normals.data.data());
    benchmark::ClobberMemory();
  }
  state.SetBytesProcessed(static_cast<int64_t>(state.iterations() * bytes_per_step(g, 2048)));
  state.counters["vertices"] = g.num_vertices();
  state.counters["steps_per_s"] =
      benchmark::Counter(static_cast<double>(state.iterations()), benchmark::Counter::kIsRate);
}

void BM_RuntimeStep(benchmark::State& state) { run_step(state, true); }
void BM_RuntimeStepRawNormals(benchmark::State& state) { run_step(state, false); }
void BM_RuntimeStepP2(benchmark::State& state) { run_step(state, true, true); }

// A step while a cross-fade runs (two spaces' frames blended): the worst case of a transition.
void BM_RuntimeStepCrossfade(benchmark::State& state) {
  const MotionGraph& g = bench_graph(static_cast<int>(state.range(0)));
  CharacterOptions o;
  o.crossfade_seconds = 5;  // long fades; a new one is started (untimed) when one ends
  Character c(g, TransitionOptions{}, o);
  c.reset(0, 1.2);
  auto start_fade = [&] {
    c.request_motion(0, c.state().p > 1.3 ? 1.1 : 1.5, 0.5);  // self-loop transition
    for (int k = 0; k < 2000 && !c.state().fading; ++k) c.step(1.0 / 60);
  };
  start_fade();
  if (!c.state().fading) state.SkipWithError("no cross-fade started");
  for (auto _ : state) {
    if (!c.state().fading) {
      state.PauseTiming();
      start_fade();
      state.ResumeTiming();
    }
    const CharacterFrame& f = c.step(1.0 / 60);
    benchmark::DoNotOptimize(f.positions.data.data());
    benchmark::ClobberMemory();
  }
}

BENCHMARK(BM_RuntimeStep)->Arg(16)->Arg(3000)->Arg(10000)->Arg(50000)->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_RuntimeStepP2)->Arg(3000)->Arg(10000)->Arg(50000)->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_RuntimeStepRawNormals)->Arg(3000)->Arg(10000)->Arg(50000)->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_RuntimeStepCrossfade)->Arg(3000)->Arg(10000)->Arg(50000)->Unit(benchmark::kMicrosecond);

}  // namespace
}  // namespace fourd
