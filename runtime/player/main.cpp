// fourd-play: the headless player. Plays an asset under a control script (runtime/player.h)
// and writes the mesh sequence (PLY per frame), frames.csv, transitions.jsonl, summary.json;
// with --render, PNG frames of the character (runtime/player/render.h) and optionally an MP4.
#include <CLI/CLI.hpp>

#include <cstdio>
#include <memory>
#include <string>

#include "pipeline/core/command_line.h"
#include "pipeline/core/error.h"
#include "pipeline/core/guarded.h"
#include "pipeline/core/log.h"
#include "runtime/asset.h"
#include "runtime/player.h"
#include "runtime/player/render.h"

int main(int argc, char** argv) {
  using namespace fourd;
  CLI::App app{"Headless player: plays a motion graph asset (asset/motion_graph.fourd) under a "
               "control script (timeline of parameter changes and motion requests, or a Bezier "
               "path to follow) and writes the meshes and per-frame logs; with --render, PNG "
               "frames of the textured character (shaded when the asset has no textures) and, "
               "with ffmpeg on PATH, an MP4.",
               "fourd-play"};
  std::string asset_path, script_path, out_dir;
  PlayerOptions options;
  bool no_meshes = false, verbose = false;
  app.add_option("asset", asset_path, "the asset file (motion_graph.fourd)")->required();
  app.add_option("script", script_path, "the control script")->required();
  app.add_option("-o,--out", out_dir, "output folder")->required();
  app.add_option("--fps", options.fps, "output frame rate (default: the script's, else 30)")
      ->check(CLI::PositiveNumber);
  app.add_option("--duration", options.duration, "seconds to play (default: the script's)")
      ->check(CLI::NonNegativeNumber);
  app.add_option("--mesh-every", options.mesh_every, "write every n-th frame's mesh")
      ->check(CLI::PositiveNumber);
  app.add_flag("--no-meshes", no_meshes, "write the logs only");
  app.add_option("--crossfade", options.character.crossfade_seconds,
                 "cross-fade at a transition's switch [s]");
  app.add_option("--crossfade-max", options.character.crossfade_max_seconds,
                 "longest cross-fade [s] (the fade adapts to the gap at the switch)");
  app.add_flag("--switch-alignment", options.character.align_at_switch,
               "fit the target's shape onto the source's at a switch (the root takes the fit on)");
  app.add_option("--tick", options.character.tick_seconds, "integration tick [s]");
  app.add_option("--depth", options.transitions_depth, "trellis depth (default: the asset's)");
  RenderOptions render;
  std::string render_dir, image_size;
  app.add_option("--render", render_dir, "write PNG frames of the character into this folder");
  app.add_option("--camera", render.camera,
                 "render camera: follow (orbit camera tracking the root) or studio:N (camera N, "
                 "from 0, of --calibration)")
      ->capture_default_str();
  app.add_option("--calibration", render.calibration,
                 "the session's calibration/ folder (COLMAP text model), for --camera studio:N");
  app.add_option("--image-size", image_size,
                 "rendered image size WxH (default: 640x480 follow, the camera's own studio)");
  app.add_option("--follow-distance", render.distance, "follow camera: distance [m]")
      ->capture_default_str();
  app.add_option("--follow-elevation", render.elevation,
                 "follow camera: angle above the ground [deg]")
      ->capture_default_str();
  app.add_option("--follow-azimuth", render.azimuth,
                 "follow camera: world direction from the character [deg, from +x]")
      ->capture_default_str();
  app.add_option("--orbit", render.orbit, "follow camera: circles the character [deg/s]")
      ->capture_default_str();
  app.add_option("--render-every", render.every, "render every n-th frame")
      ->capture_default_str();
  app.add_option("--mp4", render.mp4,
                 "also encode the rendered frames into this MP4 (needs ffmpeg on PATH; without "
                 "it a warning, and the PNGs are kept)");
  app.add_flag("-v,--verbose", verbose, "debug messages");
  if (const auto code = parse_command_line(app, argc, argv)) return *code;
  if (verbose) log::set_level(log::Level::kDebug);
  options.out_dir = out_dir;
  options.write_meshes = !no_meshes;
  if (render_dir.empty() && (!render.mp4.empty() || !image_size.empty() ||
                             app.count("--camera") > 0 || app.count("--calibration") > 0)) {
    log::error("fourd-play: --camera, --calibration, --image-size and --mp4 need --render DIR");
    return kExitUsage;
  }
  if (!image_size.empty()) {
    int w = 0, h = 0;
    char x = 0, extra = 0;
    if (std::sscanf(image_size.c_str(), "%d%c%d%c", &w, &x, &h, &extra) != 3 || x != 'x' ||
        w < 1 || h < 1) {
      log::error("fourd-play: --image-size '{}': expected WxH, e.g. 640x480", image_size);
      return kExitUsage;
    }
    render.width = w;
    render.height = h;
  }
  render.dir = render_dir;
  return run_guarded("fourd-play", [&]() -> int {
    log::Timer timer;
    const Asset asset = load_asset(asset_path);
    log::info("asset {}: {} motion spaces, {} edges, {} vertices, loaded in {:.2f} s",
              asset_path, asset.graph.spaces.size(), asset.graph.edges.size(),
              asset.graph.num_vertices(), timer.seconds());
    const ControlScript script = read_control_script(script_path);
    std::unique_ptr<FrameRenderer> renderer;
    if (!render_dir.empty()) {
      renderer = std::make_unique<FrameRenderer>(asset.graph, render);
      options.observer = renderer.get();
    }
    const PlayerReport report = run_player(asset, script, options);
    if (renderer) {
      renderer->finish(options.fps > 0 ? options.fps : script.fps);
      log::info("rendered {} frames into {}", renderer->stats().size(), render_dir);
    }
    if (report.followed_path) {
      log::info("path {:.3f} m, travelled {:.3f} m, max error {:.3f} m, {}", report.path_length,
                report.travelled, report.max_path_error, report.path_done ? "done" : "not done");
    }
    log::info("fourd-play finished in {:.1f} s ({} warnings)", timer.seconds(),
              log::warning_count());
    return kExitOk;
  });
}
