// Registration of the align stage on an articulated figure (1.7 m, arms joined to the trunk):
// finding a frame's tips on a frame re-meshed on the oracle's 8 mm grid, and registering a
// 2,000-vertex template to a frame whose right arm moved from hanging to straight forward,
// without the tip landmarks (one pass) and with them (the pass, the tips, and the retry).
#include <benchmark/benchmark.h>

#include "pipeline/geometry/measures.h"
#include "pipeline/geometry/remesh.h"
#include "pipeline/geometry/solid.h"
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

}  // namespace
}  // namespace fourd::align
