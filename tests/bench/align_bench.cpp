// Registration of the align stage on an articulated figure (1.7 m, arms joined to the trunk):
// finding a frame's tips on a frame re-meshed on the oracle's 8 mm grid, and registering a
// 2,000-vertex template to a frame whose right arm moved from hanging to straight forward,
// without the tip landmarks (one pass) and with them (the pass, the tips, and the retry).
// At real sizes (issue #46, item 4): one pair registration of a 10,000-vertex template to a
// 10,000-vertex frame a walking step later, and the whole stage on 12 walking frames of
// 20,000 vertices each (what a studio's reconstructions or another tool's meshes hold), per
// frame.
#include <benchmark/benchmark.h>
#include <stdlib.h>
#include <sys/resource.h>

#include <cmath>
#include <filesystem>
#include <fmt/format.h>
#include <fstream>

#include "pipeline/core/mesh_io.h"
#include "pipeline/core/session.h"
#include "pipeline/geometry/measures.h"
#include "pipeline/geometry/remesh.h"
#include "pipeline/geometry/solid.h"
#include "stages/align/align.h"
#include "stages/align/extremities.h"
#include "stages/align/registration.h"
#include "tests/align/align_test_data.h"

namespace fourd::align {
namespace {

struct ArmRaised {
  test::Figure figure = test::make_figure(0.012, 1.0, 0.17);
  Mesh templ = remesh_to_vertex_count(figure.rest, 2000);
  Mesh frame;

  ArmRaised() {
    test::Pose pose = test::rest_pose(figure);
    pose.rotation[4] = test::rot(-90, Eigen::Vector3d::UnitY());
    frame = remesh_fresh(test::pose_figure(figure, pose), 0.008, {0.0031, 0.0017, 0.0043});
  }
};

const ArmRaised& arm_raised() {
  static const ArmRaised data;
  return data;
}

void BM_FindExtremities(benchmark::State& state) {
  const Mesh& frame = arm_raised().frame;
  const std::vector<std::vector<int>> rings = edge_neighbours(frame);
  for (auto _ : state) {
    benchmark::DoNotOptimize(find_extremities(frame, rings, 0, ExtremityOptions{}));
  }
  state.counters["vertices"] = static_cast<double>(frame.num_vertices());
}
BENCHMARK(BM_FindExtremities)->Unit(benchmark::kMillisecond);

void BM_RegisterArmRaised(benchmark::State& state) {
  const ArmRaised& data = arm_raised();
  RegistrationOptions options;
  if (state.range(0) == 0) options.landmark_weight = 0;
  const TemplateModel model = build_template_model(data.templ, options);
  const SurfaceQuery target(data.frame);
  for (auto _ : state) {
    benchmark::DoNotOptimize(register_to_surface(model, rest_state(model), target, options));
  }
}
BENCHMARK(BM_RegisterArmRaised)->Arg(0)->Arg(1)->Unit(benchmark::kMillisecond)->UseRealTime();

// The figure (6 mm isosurface) in a walk pose at `phase`, re-meshed with connectivity of its
// own to about `vertices` vertices (the grid's voxel chosen for that count).
Mesh walking_frame(const test::Figure& figure, double phase, int vertices, int seed) {
  const Mesh posed = test::pose_figure(figure, test::walk_pose(figure, phase, 0.04 * phase));
  const Eigen::Vector3d offset(0.0011 * seed, 0.0023, 0.0007 * seed);
  // Vertex count goes as 1 / voxel^2: one trial grid, then the voxel for the count.
  const double trial = 0.01;
  const double n = static_cast<double>(remesh_fresh(posed, trial, offset).num_vertices());
  return remesh_fresh(posed, trial * std::sqrt(n / vertices), offset);
}

// CPU seconds of the whole process (every thread) so far: the machine is shared, and the work a
// benchmark does is its CPU time; its wall time on 2 free cores is about half of that.
double process_cpu_seconds() {
  rusage usage{};
  getrusage(RUSAGE_SELF, &usage);
  return static_cast<double>(usage.ru_utime.tv_sec + usage.ru_stime.tv_sec) +
         1e-6 * static_cast<double>(usage.ru_utime.tv_usec + usage.ru_stime.tv_usec);
}

const test::Figure& fine_figure() {
  static const test::Figure figure = test::make_figure(0.006, 1.0, 0.17);
  return figure;
}

struct WalkPair {
  Mesh templ, frame;
  WalkPair() {
    templ = remesh_to_vertex_count(walking_frame(fine_figure(), 0.0, 12000, 1), 10000);
    frame = walking_frame(fine_figure(), 0.6, 10000, 2);
  }
};

// The function align registers every frame with (registration.h), tip retries included, from
// the template at rest to a frame a walking step (0.6 rad of the gait cycle) later.
void BM_RegisterPair10k(benchmark::State& state) {
  static const WalkPair data;
  const RegistrationOptions options;
  const TemplateModel model = build_template_model(data.templ, options);
  const SurfaceQuery target(data.frame);
  DeformationState fit;
  const double cpu = process_cpu_seconds();
  for (auto _ : state) {
    fit = register_to_surface(model, rest_state(model), target, options);
    benchmark::DoNotOptimize(fit.positions.data());
  }
  state.counters["cpu_s"] = (process_cpu_seconds() - cpu) / static_cast<double>(state.iterations());
  const FitStats stats = evaluate_fit(model, fit.positions, target, options);
  state.counters["template_vertices"] = static_cast<double>(data.templ.num_vertices());
  state.counters["frame_vertices"] = static_cast<double>(data.frame.num_vertices());
  state.counters["surface_rms_mm"] = 1e3 * stats.surface_rms;
  state.counters["reverse_rms_mm"] = 1e3 * stats.reverse_rms;
}
BENCHMARK(BM_RegisterPair10k)
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime()
    ->MeasureProcessCPUTime()
    ->Iterations(1);

// The align stage as `fourd-align` runs it (reading the frames, shape histograms, tree,
// template of the default 3,000 vertices, registration along the tree, retries, the
// self-diagnosis, writing) on two takes of 6 walking frames of about 20,000 vertices each;
// time per frame of the whole stage's wall time.
void BM_AlignStage20kFrames(benchmark::State& state) {
  namespace fs = std::filesystem;
  std::string pattern = (fs::temp_directory_path() / "fourd_align_bench_XXXXXX").string();
  if (::mkdtemp(pattern.data()) == nullptr) {
    state.SkipWithError("mkdtemp failed");
    return;
  }
  const fs::path root = pattern;
  {
    std::ofstream out(root / "session.yaml");
    out << "name: align_bench\nfps: 12\nmotions:\n"
           "  - {name: walk, takes: [walk_a, walk_b], parameter: speed, cyclic: true}\n";
  }
  const int per_take = 6;
  double vertices = 0;
  for (int t = 0; t < 2; ++t) {
    for (int f = 0; f < per_take; ++f) {
      const double phase = 3.0 * t + 0.5 * f;
      const Mesh frame = walking_frame(fine_figure(), phase, 20000, 6 * t + f);
      vertices += static_cast<double>(frame.num_vertices());
      const fs::path file = root / "reconstruct" / (t ? "walk_b" : "walk_a") / fmt::format("{:06d}.ply", f);
      fs::create_directories(file.parent_path());
      write_ply(file, frame);
    }
  }
  StageArgs args;
  args.session_dir = root.string();
  const double cpu = process_cpu_seconds();
  for (auto _ : state) run_align(Session::open(root), args);
  const double frames = static_cast<double>(state.iterations()) * 2 * per_take;
  state.counters["frame_vertices"] = vertices / (2 * per_take);
  state.counters["frames"] = 2 * per_take;
  state.counters["s_per_frame"] =
      benchmark::Counter(frames, benchmark::Counter::kIsRate | benchmark::Counter::kInvert);
  state.counters["cpu_s_per_frame"] = (process_cpu_seconds() - cpu) / frames;
  std::error_code ec;
  fs::remove_all(root, ec);
}
BENCHMARK(BM_AlignStage20kFrames)
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime()
    ->MeasureProcessCPUTime()
    ->Iterations(1);

}  // namespace
}  // namespace fourd::align
