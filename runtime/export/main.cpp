// fourd-export: writes an asset as binary glTF 2.0 (.glb): the template mesh, every captured take
// as an animation clip and optionally the baked result of a control script (runtime/gltf_export.h).
#include <CLI/CLI.hpp>

#include <filesystem>
#include <string>

#include "pipeline/core/command_line.h"
#include "pipeline/core/error.h"
#include "pipeline/core/files.h"
#include "pipeline/core/guarded.h"
#include "pipeline/core/log.h"
#include "runtime/asset.h"
#include "runtime/gltf_export.h"
#include "runtime/player.h"

int main(int argc, char** argv) {
  using namespace fourd;
  CLI::App app{"glTF 2.0 export: writes a motion graph asset (asset/motion_graph.fourd) as one "
               "binary .glb: the template mesh, every captured take as an animation clip named "
               "after the take (one morph target per frame, the root motion on the node) and, "
               "with --script, the frames a control script plays as one more clip.",
               "fourd-export"};
  std::string asset_path, out_path, script_path, clip_name;
  PlayerOptions player;
  GlbOptions glb;
  bool verbose = false;
  app.add_option("asset", asset_path, "the asset file (motion_graph.fourd)")->required();
  app.add_option("-o,--out", out_path, "the .glb to write")->required();
  app.add_option("--script", script_path,
                 "a control script (see fourd-play) whose result is baked as one more clip");
  app.add_option("--clip-name", clip_name,
                 "name of the script's clip (default: the script's file name without extension)");
  app.add_option("--fps", player.fps, "frame rate of the script's clip (default: the script's)")
      ->check(CLI::PositiveNumber);
  app.add_option("--duration", player.duration, "seconds of the script to bake (default: the "
                 "script's)")
      ->check(CLI::NonNegativeNumber);
  app.add_flag("--compress", glb.compress,
               "compress: EXT_meshopt_compression and quantised vertices (KHR_mesh_quantization); "
               "a viewer needs meshoptimizer's decoder (three.js: MeshoptDecoder)");
  app.add_option("--position-step", glb.position_step_mm,
                 "with --compress: grid step of the quantised positions [mm]; a decoded vertex "
                 "is within step * sqrt(3) of the exact one")
      ->capture_default_str();
  app.add_option("--texture-size", glb.texture_size,
                 "resize the texture so its longer side has this many pixels (0: as is)")
      ->capture_default_str();
  app.add_option("--texture-format", glb.texture_format, "png | jpeg | webp (EXT_texture_webp)")
      ->capture_default_str();
  app.add_option("--texture-quality", glb.texture_quality, "jpeg / webp quality (1..100)")
      ->capture_default_str();
  app.add_flag("-v,--verbose", verbose, "debug messages");
  if (const auto code = parse_command_line(app, argc, argv)) return *code;
  if (verbose) log::set_level(log::Level::kDebug);
  return run_guarded("fourd-export", [&]() -> int {
    log::Timer timer;
    glb.check();
    // An output folder that cannot be made fails now, not after the work.
    const std::filesystem::path out_dir = std::filesystem::path(out_path).parent_path();
    if (!out_dir.empty()) ensure_directory(out_dir);
    const Asset asset = load_asset(asset_path);
    MeshAnimation animation;
    animation.name = asset.graph.name;
    animation.base = asset_template(asset);
    animation.texture_png = asset_template_texture_png(asset);
    animation.clips = asset_take_clips(asset);
    if (!script_path.empty()) {
      const ControlScript script = read_control_script(script_path);
      const std::string name =
          clip_name.empty() ? std::filesystem::path(script_path).stem().string() : clip_name;
      animation.clips.push_back(bake_control_script(asset, script, player, name));
    }
    int frames = 0;
    for (const MeshClip& clip : animation.clips) frames += clip.num_frames();
    write_mesh_animation_glb(out_path, animation, glb);
    log::info("{}: {} vertices, {} clips, {} morph targets, {}{}, {:.1f} MB in {:.1f} s",
              out_path, animation.base.num_vertices(), animation.clips.size(), frames,
              animation.texture_png.empty() ? "no texture" : "textured",
              glb.compress ? ", compressed" : "",
              std::filesystem::file_size(out_path) / 1e6, timer.seconds());
    return kExitOk;
  });
}
