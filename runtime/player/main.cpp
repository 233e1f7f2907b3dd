// fourd-play: the headless player. Plays an asset under a control script (runtime/player.h)
// and writes the mesh sequence (PLY per frame), frames.csv, transitions.jsonl, summary.json.
#include <CLI/CLI.hpp>

#include <string>

#include "pipeline/core/error.h"
#include "pipeline/core/log.h"
#include "runtime/asset.h"
#include "runtime/player.h"

int main(int argc, char** argv) {
  using namespace fourd;
  CLI::App app{"Headless player: plays a motion graph asset (asset/motion_graph.fourd) under a "
               "control script (timeline of parameter changes and motion requests, or a Bezier "
               "path to follow) and writes the meshes and per-frame logs.",
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
  app.add_option("--tick", options.character.tick_seconds, "integration tick [s]");
  app.add_option("--depth", options.transitions_depth, "trellis depth (default: the asset's)");
  app.add_flag("-v,--verbose", verbose, "debug messages");
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e) == 0 ? kExitOk : kExitUsage;
  }
  if (verbose) log::set_level(log::Level::kDebug);
  options.out_dir = out_dir;
  options.write_meshes = !no_meshes;
  try {
    log::Timer timer;
    const Asset asset = load_asset(asset_path);
    log::info("asset {}: {} motion spaces, {} edges, {} vertices, loaded in {:.2f} s",
              asset_path, asset.graph.spaces.size(), asset.graph.edges.size(),
              asset.graph.num_vertices(), timer.seconds());
    const ControlScript script = read_control_script(script_path);
    const PlayerReport report = run_player(asset, script, options);
    if (report.followed_path) {
      log::info("path {:.3f} m, travelled {:.3f} m, max error {:.3f} m, {}", report.path_length,
                report.travelled, report.max_path_error, report.path_done ? "done" : "not done");
    }
    log::info("fourd-play finished in {:.1f} s ({} warnings)", timer.seconds(),
              log::warning_count());
    return kExitOk;
  } catch (const Error& e) {
    log::error("fourd-play: {}", e.what());
    return e.exit_code();
  } catch (const std::exception& e) {
    log::error("fourd-play: internal error: {}", e.what());
    return kExitFailure;
  }
}
