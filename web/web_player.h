#pragma once
// The web player's side in WebAssembly (docs/web.md): everything but drawing. Loads an asset,
// plays it with the runtime's Character under a Controller like fourd-view, takes the page's
// input (keys held, key presses, clicks on the ground) and hands the page what it draws: the
// blended positions and normals (root frame, planes x | y | z, runtime/blend.h), the root, the
// key textures to blend and their weights, the camera matrices (the viewer's OrbitCamera) and
// the state for the HUD. A control script runs through fourd-play's own player (run_player), so
// the page reports the positions fourd-play writes. The bindings (bindings.cpp) expose it to
// JavaScript; this file has no Emscripten dependency.
#include <array>
#include <chrono>
#include <cstdint>
#include <string>
#include <vector>

#include "runtime/asset.h"
#include "runtime/character.h"
#include "runtime/controller.h"
#include "runtime/viewer/view_math.h"
#include "web/step_benchmark.h"

namespace fourd::web {

// Keys held during a frame (a bit mask from the page).
enum HeldKey : int { kFaster = 1, kSlower = 2, kTurnLeft = 4, kTurnRight = 8 };

// A script run: the world positions of the recorded frames (our axes).
struct ScriptRun {
  int frames = 0;
  std::vector<int> recorded;         // frame indices recorded
  std::vector<float> positions;      // recorded.size() x #V x 3
  std::string summary;               // JSON: frames, duration, transitions, refused, clamped
};

class WebPlayer {
 public:
  // Throws what load_asset throws.
  explicit WebPlayer(const std::string& asset_path);

  // The asset.
  const Asset& asset() const { return asset_; }
  int num_vertices() const;
  int plane_stride() const;
  const std::vector<std::int32_t>& triangle_indices() const { return triangles_; }
  const std::vector<float>& corner_uvs() const { return corner_uvs_; }  // #F x 3 x (u, v)
  std::string info_json() const;  // name, fps, spaces (name, parameter, unit, range, cyclic)

  // Live play. `dt`: seconds of wall-clock time since the last frame; `keys`: HeldKey bits.
  // Returns the runtime's time for the step [ms].
  double frame(double dt, int keys);
  void jump();
  void jump_height();
  void reach();              // at the reach offset from the character
  void request_motion(const std::string& space, double p);
  void set_speed(double speed);
  void set_heading_deg(double heading);
  void set_jump_length(double length) { jump_length_ = length; }
  void set_time_scale(double scale) { time_scale_ = scale; }
  void set_paused(bool paused) { paused_ = paused; }
  // A click at pixel (x, y) of the canvas: mode 0 walks towards the ground point, 1 reaches it
  // (at the reach height). False when the ray misses the ground.
  bool click(double x, double y, int mode);

  // Camera (the viewer's OrbitCamera); matrices column-major, for a width x height canvas.
  void camera_drag(double dx, double dy) { camera_.rotate(static_cast<float>(dx), static_cast<float>(dy)); }
  void camera_zoom(double steps) { camera_.zoom(static_cast<float>(steps)); }
  void toggle_camera_mode();
  void set_viewport(int width, int height);
  const float* view_projection() const { return view_projection_.data(); }
  const float* eye() const { return eye_.data(); }

  // The frame to draw (live, or the one a script run kept).
  const CharacterFrame& shown() const { return shown_ ? *shown_ : character_.frame(); }
  std::string state_json() const;  // motion, phase, parameter, t, time, root, request, following

  // Runs `script` as fourd-play does (fps from the script), recording the world positions of
  // every `record_every`-th frame; frame `show_frame` (>= 0) becomes the shown frame. Throws
  // InputError for a bad script.
  const ScriptRun& run_script(const std::string& text, int record_every, int show_frame);
  const ScriptRun& run_script_result() const { return run_; }
  void show_live() { shown_ = nullptr; }

 private:
  void apply_walk();
  void note(const RequestStatus& status, const std::string& what);
  Eigen::Vector3f reach_world() const;

  Asset asset_;
  std::vector<std::int32_t> triangles_;
  std::vector<float> corner_uvs_;
  Character character_;
  Controller controller_;
  viewer::OrbitCamera camera_;
  viewer::Mat4f view_ = viewer::Mat4f::Identity(), projection_ = viewer::Mat4f::Identity();
  viewer::Mat4f view_projection_ = viewer::Mat4f::Identity();
  Eigen::Vector3f eye_ = Eigen::Vector3f::Zero();
  int width_ = 1, height_ = 1;

  int locomotion_ = -1, jump_ = -1, jump_height_space_ = -1, reach_ = -1;
  double speed_ = 1, heading_ = 0, jump_length_ = 1, jump_height_ = 0.3;
  std::array<double, 3> reach_offset_{1.5, 0, 1.2};  // forward, left, height [m]
  bool walk_pending_ = false;
  double time_scale_ = 1;
  bool paused_ = false;
  std::string request_text_;
  double step_ms_ = 0;

  ScriptRun run_;
  CharacterFrame kept_;                  // the script run's shown frame
  const CharacterFrame* shown_ = nullptr;
};

}  // namespace fourd::web
