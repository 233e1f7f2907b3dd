// The texture stage's per-frame work at the default resolution (1024x1024 texels) on what the
// default sample gives it: the procedural performer (~5,000 vertices) filmed by the default rig
// (8 cameras, 640x480) in the virtual studio. Baking alone, and baking plus writing the PNG
// texture and the unseen mask (the stage's whole per-frame cost besides reading the images);
// and building the atlas, done once per run.
#include <benchmark/benchmark.h>
#include <unistd.h>

#include <filesystem>

#include "pipeline/exchange/texture_image.h"
#include "stages/synth/character.h"
#include "stages/synth/render.h"
#include "stages/texture/atlas.h"
#include "stages/texture/bake.h"

namespace fourd::texture {
namespace {

struct Studio {
  synth::Character character = synth::make_procedural_character(synth::CharacterOptions{}, 7);
  Mesh performer = synth::skin_mesh(character.skin,
                                    synth::forward_kinematics(character.skeleton,
                                                              synth::rest_pose(character.skeleton)));
  std::vector<Camera> cameras = synth::make_rig(synth::RigOptions{});
  std::vector<View> views;
  Atlas atlas;
  TexelMap texels;

  Studio() {
    synth::StudioRenderer renderer{synth::StudioOptions{}};
    renderer.set_performer(performer, character.texture);
    for (std::size_t c = 0; c < cameras.size(); ++c) {
      views.push_back({&cameras[c], renderer.render(cameras[c], c).image});
    }
    atlas = build_atlas(performer, AtlasOptions{});
    texels = map_texels(atlas, performer.triangles);
  }
};

const Studio& studio() {
  static const Studio s;
  return s;
}

void BM_BuildAtlas(benchmark::State& state) {
  const Studio& s = studio();
  for (auto _ : state) {
    Atlas atlas = build_atlas(s.performer, AtlasOptions{});
    benchmark::DoNotOptimize(atlas.uvs.data());
  }
  state.counters["charts"] = static_cast<double>(s.atlas.charts.size());
  state.counters["vertices"] = static_cast<double>(s.performer.num_vertices());
}
BENCHMARK(BM_BuildAtlas)->Unit(benchmark::kMillisecond)->UseRealTime();

void BM_BakeFrame1024(benchmark::State& state) {
  const Studio& s = studio();
  BakedTexture baked;
  for (auto _ : state) {
    baked = bake_texture(s.atlas, s.texels, s.performer.positions, s.performer.triangles, s.views,
                         BakeOptions{});
    benchmark::DoNotOptimize(baked.color.data);
  }
  state.counters["texels"] = baked.texels;
  state.counters["unseen_pct"] = 100.0 * baked.unseen_texels / std::max(1, baked.texels);
}
BENCHMARK(BM_BakeFrame1024)->Unit(benchmark::kMillisecond)->UseRealTime();

void BM_BakeAndWriteFrame1024(benchmark::State& state) {
  const Studio& s = studio();
  const std::filesystem::path dir =
      std::filesystem::temp_directory_path() / ("fourd_texture_bench_" + std::to_string(::getpid()));
  for (auto _ : state) {
    const BakedTexture baked = bake_texture(s.atlas, s.texels, s.performer.positions,
                                            s.performer.triangles, s.views, BakeOptions{});
    write_texture(dir / "000000.png", texture_for_output(baked.color, false));
    write_texture(dir / "unseen" / "000000.png", baked.unseen);
  }
  std::filesystem::remove_all(dir);
}
BENCHMARK(BM_BakeAndWriteFrame1024)->Unit(benchmark::kMillisecond)->UseRealTime();

}  // namespace
}  // namespace fourd::texture
