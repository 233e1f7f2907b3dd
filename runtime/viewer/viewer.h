#pragma once
// fourd-view: the interactive viewer. Loads an asset (runtime/asset.h), plays it with a runtime
// Character under a Controller (runtime/character.h, runtime/controller.h) every frame, and draws
// it with OpenGL 3.3 (runtime/viewer/renderer.h) in a GLFW window with Dear ImGui panels.
//
// Headless use (under Xvfb): `screenshot` renders `frames` frames at a fixed step of motion time
// and saves the last one as PNG; `benchmark_seconds` renders for that long at the real frame
// time and reports the frame rate.
#include <filesystem>
#include <limits>
#include <string>

#include "runtime/viewer/view_math.h"

namespace fourd::viewer {

struct ViewerOptions {
  std::filesystem::path asset;
  int width = 1280;   // [pixels] window
  int height = 720;
  std::filesystem::path screenshot;  // non-empty: save frame `frames` as PNG and exit
  int frames = 60;                   // frames rendered before the screenshot
  double benchmark_seconds = 0;      // > 0: render this long, report the FPS and exit
  double fixed_step = 0;  // [s] > 0: every frame advances motion time by this (default with a
                          // screenshot: 1/30), else by the measured frame time
  bool show_ui = true;    // ImGui panels
  CameraMode camera = CameraMode::kFollow;
  float camera_distance = OrbitCamera{}.distance;  // [m] from the point looked at
  std::string start_space;  // empty: the locomotion space, else the first
  double start_parameter = std::numeric_limits<double>::quiet_NaN();  // NaN: middle of range
  bool vsync = true;  // interactive only; headless runs never wait for the display
  // A control script of the headless player (runtime/player.h): its start, path and timed
  // events drive the character as they would fourd-play (fps and duration are ignored). Empty:
  // none.
  std::filesystem::path script;

  // Throws ConfigError naming the field.
  void check() const;
};

struct ViewerReport {
  int frames = 0;
  double seconds = 0;        // wall-clock time of the frame loop
  double fps = 0;            // frames / seconds
  double mean_frame_ms = 0;  // wall-clock per frame
  double max_frame_ms = 0;
  bool textured = false;     // the key textures were uploaded (else shading only)
  int vertices = 0;
  int triangles = 0;
};

// Runs the viewer until the window is closed (or the screenshot is written, or the benchmark
// time is up). Throws InputError / IoError naming the file for a bad asset or script, IoError
// when the screenshot cannot be written, Error when no OpenGL 3.3 window can be opened.
ViewerReport run_viewer(const ViewerOptions& options);

}  // namespace fourd::viewer
