// fourd-export: writes an asset as binary glTF 2.0 (.glb): the template mesh, every captured take
// as an animation clip and optionally the baked result of a control script (runtime/gltf_export.h);
// and/or one take or the script's result as a mesh sequence (runtime/mesh_sequence.h); and/or the
// asset's web package (runtime/asset_packing.h).
#include <CLI/CLI.hpp>
#include <fmt/format.h>
#include <fmt/ranges.h>

#include <filesystem>
#include <string>

#include "pipeline/core/command_line.h"
#include "pipeline/core/error.h"
#include "pipeline/core/files.h"
#include "pipeline/core/guarded.h"
#include "pipeline/core/log.h"
#include "runtime/asset.h"
#include "runtime/asset_packing.h"
#include "runtime/gltf_export.h"
#include "runtime/mesh_sequence.h"
#include "runtime/player.h"

int main(int argc, char** argv) {
  using namespace fourd;
  CLI::App app{"glTF 2.0 export: writes a motion graph asset (asset/motion_graph.fourd) as one "
               "binary .glb: the template mesh, every captured take as an animation clip named "
               "after the take (one morph target per frame, the root motion on the node) and, "
               "with --script, the frames a control script plays as one more clip; with "
               "--sequence, one take (--take) or the script's result as one mesh file and "
               "texture per frame with a sequence.json manifest; with --web, the asset packaged "
               "for the web player (quantised, delta-coded geometry, gzip).",
               "fourd-export"};
  std::string asset_path, out_path, script_path, clip_name, sequence_dir, take, web_path;
  AssetPacking packing;
  PlayerOptions player;
  GlbOptions glb;
  SequenceOptions sequence;
  bool verbose = false;
  app.add_option("asset", asset_path, "the asset file (motion_graph.fourd)")->required();
  app.add_option("-o,--out", out_path, "the .glb to write");
  app.add_option("--sequence", sequence_dir,
                 "write a mesh sequence of --take or of the --script's result into this folder");
  app.add_option("--take", take, "with --sequence: the captured take to write");
  app.add_option("--sequence-format", sequence.format, "with --sequence: ply | obj")
      ->capture_default_str();
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
                 "with --compress: grid step of the quantised vertex displacements [mm]; a "
                 "decoded vertex is within step * sqrt(3) / 2 of the exact one")
      ->capture_default_str();
  app.add_option("--texture-size", glb.texture.size,
                 "resize the texture (the .glb's, and the sequence's per frame) so its longer "
                 "side has this many pixels (0: as is)")
      ->capture_default_str();
  app.add_option("--texture-format", glb.texture.format, "png | jpeg | webp (EXT_texture_webp)")
      ->capture_default_str();
  app.add_option("--texture-quality", glb.texture.quality, "jpeg / webp quality (1..100)")
      ->capture_default_str();
  app.add_option("--web", web_path,
                 "write the asset's web package (docs/web.md) to this file: geometry quantised "
                 "and delta-coded, gzip; the web player and every loader of the runtime read it");
  app.add_option("--web-position-step", packing.position_step,
                 "with --web: grid step of the input frames' positions [m] (error <= step / 2 "
                 "per coordinate)")
      ->capture_default_str();
  app.add_option("--web-displacement-step", packing.displacement_step,
                 "with --web: grid step of the references' displacements [m]")
      ->capture_default_str();
  app.add_option("--web-normal-bits", packing.normal_bits,
                 "with --web: bits per octahedral coordinate of the input normals (8..16)")
      ->capture_default_str();
  app.add_flag("-v,--verbose", verbose, "debug messages");
  if (const auto code = parse_command_line(app, argc, argv)) return *code;
  if (verbose) log::set_level(log::Level::kDebug);
  return run_guarded("fourd-export", [&]() -> int {
    log::Timer timer;
    glb.check();
    sequence.texture = glb.texture;
    sequence.check();
    packing.check();
    if (out_path.empty() && sequence_dir.empty() && web_path.empty())
      throw UsageError("nothing to write: give -o FILE.glb, --sequence DIR and/or --web FILE");
    if (!sequence_dir.empty() && take.empty() == script_path.empty())
      throw UsageError("--sequence needs one of --take NAME or --script FILE");
    if (!take.empty() && sequence_dir.empty())
      throw UsageError("--take is for --sequence");
    // An output folder that cannot be made fails now, not after the work.
    for (const std::filesystem::path& out : {std::filesystem::path(out_path).parent_path(),
                                            std::filesystem::path(sequence_dir).parent_path(),
                                            std::filesystem::path(web_path).parent_path()})
      if (!out.empty()) ensure_directory(out);
    const Asset asset = load_asset(asset_path);
    if (!web_path.empty()) {
      save_web_package(web_path, asset, packing);
      // What the package costs: read back as every loader reads it, against the original.
      const Asset decoded = load_asset(web_path);
      const PackingError error = packing_error(asset.graph, decoded.graph);
      log::info("{}: web package, {:.1f} MB (asset {:.1f} MB); decoded: positions within {:.4f} "
                "mm, normals within {:.3f} deg",
                web_path, std::filesystem::file_size(web_path) / 1e6,
                std::filesystem::file_size(asset_path) / 1e6, 1e3 * error.position_m,
                error.normal_deg);
    }
    if (out_path.empty() && sequence_dir.empty()) return kExitOk;
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
    if (!sequence_dir.empty()) {
      const MeshClip* clip = nullptr;
      for (const MeshClip& c : animation.clips)
        if (take.empty() ? &c == &animation.clips.back() : c.name == take) clip = &c;
      if (clip == nullptr) {
        std::vector<std::string> takes;
        for (const GraphSpace& space : asset.graph.spaces)
          takes.insert(takes.end(), space.motion.takes.begin(), space.motion.takes.end());
        throw UsageError(fmt::format("--take {}: the asset's takes are {}", take,
                                     fmt::join(takes, ", ")));
      }
      // A take's rate: its mean captured one; a script's: the one it played at.
      const double fps = clip->num_frames() > 1 && clip->times.back() > clip->times.front()
                             ? (clip->num_frames() - 1) / (clip->times.back() - clip->times.front())
                             : asset.graph.fps;
      const SequenceReport report =
          write_mesh_sequence(sequence_dir, asset, *clip, fps, sequence);
      log::info("{}: clip '{}', {} frames at {:.2f} fps, {:.1f} MB", sequence_dir, clip->name,
                report.frames, report.fps, report.bytes / 1e6);
    }
    if (out_path.empty()) return kExitOk;
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
