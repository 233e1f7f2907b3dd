// fourd-view: the interactive viewer (runtime/viewer/viewer.h). Also renders headless under Xvfb:
// a screenshot of a given frame, or a frame-rate benchmark.
#include <CLI/CLI.hpp>

#include <cstdio>
#include <map>
#include <string>

#include "pipeline/core/command_line.h"
#include "pipeline/core/error.h"
#include "pipeline/core/guarded.h"
#include "pipeline/core/log.h"
#include "runtime/viewer/viewer.h"

int main(int argc, char** argv) {
  using namespace fourd;
  using viewer::CameraMode;
  CLI::App app{
      "Interactive viewer: plays a motion graph asset (asset/motion_graph.fourd) on a ground "
      "plane. Keys: W/S or arrows speed, A/D turn, space jump, H jump up, R reach, P path mode "
      "(click points on the ground, Enter to follow), C follow/orbit camera; mouse drag orbits, "
      "wheel zooms. Headless (xvfb-run): --screenshot FILE --frames N, or --benchmark SECONDS.",
      "fourd-view"};
  viewer::ViewerOptions options;
  std::string asset_path, screenshot, script;
  bool no_ui = false, no_vsync = false, verbose = false;
  const std::map<std::string, CameraMode> cameras{{"follow", CameraMode::kFollow},
                                                  {"orbit", CameraMode::kOrbit}};
  app.add_option("asset", asset_path, "the asset file (motion_graph.fourd)")->required();
  app.add_option("--width", options.width, "window width [pixels]")->default_val(options.width);
  app.add_option("--height", options.height, "window height [pixels]")
      ->default_val(options.height);
  app.add_option("--screenshot", screenshot,
                 "render --frames frames, save the last as this PNG and exit");
  app.add_option("--frames", options.frames, "frames rendered before the screenshot")
      ->default_val(options.frames)
      ->check(CLI::PositiveNumber);
  app.add_option("--benchmark", options.benchmark_seconds,
                 "render for this many seconds, print the frame rate and exit")
      ->check(CLI::NonNegativeNumber);
  app.add_option("--step", options.fixed_step,
                 "motion time per frame [s] (default: the measured frame time; 1/30 with "
                 "--screenshot, so the image does not depend on the machine's speed)")
      ->check(CLI::Range(0.0, 1.0));
  app.add_option("--camera", options.camera, "follow (behind the character) or orbit")
      ->transform(CLI::CheckedTransformer(cameras, CLI::ignore_case))
      ->default_str("follow");
  app.add_option("--distance", options.camera_distance, "camera distance [m]")
      ->default_val(options.camera_distance)
      ->check(CLI::Range(1.0, 60.0));
  app.add_option("--start", options.start_space,
                 "motion space to start in (default: locomotion, else the first)");
  app.add_option("--parameter", options.start_parameter,
                 "its parameter (default: the middle of its range)");
  app.add_option("--script", script,
                 "a control script of fourd-play (runtime/player.h): its start, path and events "
                 "drive the character");
  app.add_flag("--no-ui", no_ui, "hide the panels (the scene only)");
  app.add_flag("--no-vsync", no_vsync, "do not wait for the display between frames");
  app.add_flag("-v,--verbose", verbose, "debug messages");
  if (const auto code = parse_command_line(app, argc, argv)) return *code;
  if (verbose) log::set_level(log::Level::kDebug);
  options.asset = asset_path;
  options.screenshot = screenshot;
  options.script = script;
  options.show_ui = !no_ui;
  options.vsync = !no_vsync;
  return run_guarded("fourd-view", [&]() -> int {
    const viewer::ViewerReport report = viewer::run_viewer(options);
    log::info("{} frames in {:.2f} s: {:.1f} FPS (mean frame {:.2f} ms, longest {:.2f} ms), {}",
              report.frames, report.seconds, report.fps, report.mean_frame_ms,
              report.max_frame_ms, report.textured ? "textured" : "shaded");
    if (options.benchmark_seconds > 0) {
      std::printf("fps %.1f frames %d seconds %.2f mean_frame_ms %.2f vertices %d triangles %d %s\n",
                  report.fps, report.frames, report.seconds, report.mean_frame_ms,
                  report.vertices, report.triangles, report.textured ? "textured" : "shaded");
    }
    return kExitOk;
  });
}
