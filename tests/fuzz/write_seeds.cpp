// Writes the seeds of the fuzz targets that come from the real writers on small data
// (tests/fuzz/make_corpus.py runs it): a three-camera rig (one per COLMAP camera model the
// writer uses), a five-joint skinned character in glTF with two short clips and its motion in
// BVH, a walker registered by the timewarp stage (.twarp), the tube graph of the graph tests
// (assets, and its motion spaces as .mspace).
//
// usage: fuzz_write_seeds OUT_DIR    (writes OUT_DIR/<target>/...)
#include <fmt/format.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <vector>

#include "pipeline/core/colmap_model.h"
#include "pipeline/core/error.h"
#include "pipeline/core/files.h"
#include "runtime/asset.h"
#include "runtime/motion_space.h"
#include "stages/synth/bvh_io.h"
#include "stages/synth/gltf_io.h"
#include "stages/timewarp/timewarp.h"
#include "tests/graph/test_graph.h"
#include "tests/synth/test_character.h"
#include "tests/timewarp/walker_session.h"

namespace fourd {
namespace {

void write_seeds(const fs::path& dir) {
  std::vector<Camera> rig(3);
  for (int i = 0; i < 3; ++i) {
    Camera& c = rig[i];
    c.name = fmt::format("cam{:02d}", i);
    c.intrinsics.width = 320;
    c.intrinsics.height = 240;
    c.intrinsics.fx = c.intrinsics.fy = 280 + i;
    c.intrinsics.cx = 160;
    c.intrinsics.cy = 120;
    c.intrinsics.k1 = i == 1 ? -0.05 : 0;
    c.intrinsics.p1 = i == 2 ? 1e-3 : 0;
    const double angle = 2.1 * i;
    c.camera_from_world =
        look_at({3.5 * std::cos(angle), 3.5 * std::sin(angle), 1.6}, {0, 0, 0.9}, {0, 0, 1});
  }
  write_colmap_model(dir / "colmap", rig);
  const synth::Character character = synth::test::make_test_character();
  const synth::MotionClip walk = synth::test::make_test_clip(character.skeleton, "walk", 4, 10, 1);
  const synth::MotionClip jump = synth::test::make_test_clip(character.skeleton, "jump", 3, 10, 2);
  synth::write_gltf_character(dir / "gltf" / "column.glb", character, {walk, jump});
  synth::write_bvh(dir / "bvh" / "column_walk.bvh", character.skeleton, walk.poses, walk.fps);
  test::WalkerSession s;
  s.write_standard();
  timewarp::run_timewarp(Session::open(s.root()), test::oracle_args(s.root()));
  for (const char* name : {"locomotion.twarp", "jump_length.twarp"}) {
    write_file_atomic(dir / "twarp" / name, read_file(s.root() / "timewarp_oracle" / name));
  }
  Asset asset;
  asset.graph = test::make_test_graph(true);
  save_asset(dir / "asset" / "tube_graph.fourd", asset);
  Asset small;
  small.graph = test::make_test_graph(false);
  save_asset(dir / "asset" / "tube_graph_no_turns.fourd", small);
  for (const GraphSpace& space : small.graph.spaces) {
    save_motion_space(dir / "mspace" / (space.name() + ".mspace"), space.motion);
  }
}

}  // namespace
}  // namespace fourd

int main(int argc, char** argv) {
  if (argc != 2) {
    std::fprintf(stderr, "usage: fuzz_write_seeds OUT_DIR\n");
    return fourd::kExitUsage;
  }
  try {
    fourd::write_seeds(argv[1]);
  } catch (const fourd::Error& e) {
    std::fprintf(stderr, "fuzz_write_seeds: %s\n", e.what());
    return e.exit_code();
  }
  return fourd::kExitOk;
}
