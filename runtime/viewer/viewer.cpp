#include "runtime/viewer/viewer.h"

// epoxy before GLFW, so GLFW does not pull in the system's GL header.
#include <epoxy/gl.h>
#define GLFW_INCLUDE_NONE
#include <GLFW/glfw3.h>
#include <fmt/format.h>
#include <imgui.h>
#include <backends/imgui_impl_glfw.h>
#include <backends/imgui_impl_opengl3.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <numbers>
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>
#include <vector>

#include "pipeline/core/error.h"
#include "pipeline/core/image_io.h"
#include "pipeline/core/log.h"
#include "pipeline/core/se2.h"
#include "runtime/asset.h"
#include "runtime/character.h"
#include "runtime/controller.h"
#include "runtime/player.h"
#include "runtime/viewer/renderer.h"

namespace fourd::viewer {

void ViewerOptions::check() const {
  if (width < 64 || width > 8192) throw ConfigError(fmt::format("width {} not in [64, 8192]", width));
  if (height < 64 || height > 8192) {
    throw ConfigError(fmt::format("height {} not in [64, 8192]", height));
  }
  if (!screenshot.empty() && frames < 1) throw ConfigError("frames must be >= 1 with a screenshot");
  if (benchmark_seconds < 0) throw ConfigError("benchmark seconds must be >= 0");
  if (fixed_step < 0 || fixed_step > 1) throw ConfigError("fixed step must lie in [0, 1] s");
  if (!(camera_distance >= 1 && camera_distance <= 60)) {
    throw ConfigError(fmt::format("camera distance {} not in [1, 60] m", camera_distance));
  }
}

namespace {

constexpr double kDeg = std::numbers::pi / 180;
constexpr int kTrail = 720;       // root positions kept for the trail
constexpr int kFrameHistory = 120;  // frame times plotted in the HUD
constexpr int kCurveSamples = 24;   // line segments drawn per Bezier curve

// What a click on the ground does.
enum class ClickMode : int { kWalkTowards = 0, kPathPoint = 1, kReachTarget = 2 };

struct GlfwSession {
  GlfwSession() {
    glfwSetErrorCallback([](int code, const char* text) { log::debug("GLFW {}: {}", code, text); });
    if (!glfwInit()) {
      throw Error("cannot initialise GLFW: no display? (headless: run under xvfb-run)");
    }
  }
  ~GlfwSession() { glfwTerminate(); }
};

struct GlfwWindow {
  explicit GlfwWindow(GLFWwindow* w) : window(w) {}
  ~GlfwWindow() {
    if (window) glfwDestroyWindow(window);
  }
  GLFWwindow* window;
};

struct ImGuiSession {
  explicit ImGuiSession(GLFWwindow* window) {
    IMGUI_CHECKVERSION();
    ImGui::CreateContext();
    ImGui::GetIO().IniFilename = nullptr;  // no imgui.ini beside the user's files
    ImGui::StyleColorsDark();
    ImGui_ImplGlfw_InitForOpenGL(window, true);
    ImGui_ImplOpenGL3_Init("#version 330 core");
  }
  ~ImGuiSession() {
    ImGui_ImplOpenGL3_Shutdown();
    ImGui_ImplGlfw_Shutdown();
    ImGui::DestroyContext();
  }
};

class App {
 public:
  App(const Asset& asset, const ViewerOptions& options, const ControlScript* script,
      GLFWwindow* window);
  // One frame: input, `dt` seconds of motion time, drawing. `frame_seconds` is the wall-clock
  // time of the previous frame (for the HUD).
  void frame(double dt, double frame_seconds);
  bool textured() const { return renderer_.textured(); }

 private:
  void handle_input(double dt);
  void ground_click(float x, float y);
  void apply_walk();
  void request(int space, double p, const char* what);
  void request_status(const RequestStatus& status, const std::string& what, int target);
  void draw_scene(int width, int height);
  void draw_ui();
  void draw_hud();
  void draw_controls();
  void draw_transition();
  void follow_path();
  void play_event(const ScriptEvent& e);
  Eigen::Vector3f reach_world() const;
  const GraphSpace& space(int s) const { return asset_.graph.spaces[s]; }

  const Asset& asset_;
  const ViewerOptions& options_;
  const ControlScript* script_;  // may be null
  std::size_t next_event_ = 0;
  GLFWwindow* window_;
  Character character_;
  Controller controller_;
  Renderer renderer_;
  OrbitCamera camera_;
  Mat4f view_ = Mat4f::Identity(), projection_ = Mat4f::Identity();
  int width_ = 1, height_ = 1;

  // Control.
  int locomotion_ = -1, jump_height_space_ = -1;
  float speed_ = 1;               // [m/s]
  float heading_ = 0;             // [rad] where the walk steers to
  bool walk_pending_ = false;     // speed or heading changed, not yet requested
  float jump_length_ = 1;         // [m]
  float jump_height_ = 0.3f;      // [m]
  std::array<float, 3> reach_offset_{1.5f, 0, 1.2f};  // forward, left, height [m]
  std::vector<float> space_parameter_;  // per space, the motion buttons' parameter
  ClickMode click_mode_ = ClickMode::kWalkTowards;
  bool paused_ = false;
  float time_scale_ = 1;

  // Path drawing: the root where the drawing started, then the clicked points.
  std::vector<Point2> path_points_;
  GroundPath path_;
  bool following_ = false;

  // Trail of the root (ring buffer).
  std::array<Point2, kTrail> trail_{};
  int trail_count_ = 0, trail_next_ = 0;

  // The last request.
  std::string request_text_;
  std::vector<int> route_;  // spaces visited, from the one playing at the request
  double request_time_ = -1;
  bool request_one_shot_ = false;

  // Frame times.
  std::array<float, kFrameHistory> frame_ms_{};
  int frame_index_ = 0;
  float mean_ms_ = 0;

  // Draw scratch (grown once).
  std::vector<LineVertex> lines_, points_;
  bool mouse_dragged_ = false;
};

App::App(const Asset& asset, const ViewerOptions& options, const ControlScript* script,
         GLFWwindow* window)
    : asset_(asset),
      options_(options),
      script_(script),
      window_(window),
      character_(asset.graph, asset.transitions),
      controller_(character_) {
  const MotionGraph& graph = asset.graph;
  locomotion_ = graph.find_space(ControllerOptions{}.locomotion_space);
  jump_height_space_ = graph.find_space("jump_height");
  int start = locomotion_ >= 0 ? locomotion_ : 0;
  if (!options.start_space.empty()) {
    start = graph.find_space(options.start_space);
    if (start < 0) {
      std::string names;
      for (const GraphSpace& g : graph.spaces) names += (names.empty() ? "" : ", ") + g.name();
      throw ConfigError(fmt::format("start space '{}' is not in the asset (it has: {})",
                                    options.start_space, names));
    }
  }
  for (int s = 0; s < static_cast<int>(graph.spaces.size()); ++s) {
    space_parameter_.push_back(
        static_cast<float>(0.5 * (space(s).parameter_min() + space(s).parameter_max())));
  }
  double p0 = std::isnan(options.start_parameter) ? space_parameter_[start]
                                                  : options.start_parameter;
  double t0 = 0;
  RootTransform root0;
  if (script) {
    // As fourd-play starts it: the script's space, parameter and time, on its path facing along.
    start = graph.find_space(script->start_space);
    p0 = std::isnan(script->start_p) ? space_parameter_[start] : script->start_p;
    t0 = script->start_t;
    if (!script->path.empty()) {
      path_ = GroundPath(script->path);
      const Point2 a = path_.point_at(0);
      root0 = {a.x, a.y, path_.heading_at(0)};
      heading_ = static_cast<float>(root0.heading);
      camera_.follow_heading = heading_;
    }
  }
  const RequestStatus started = character_.reset(start, p0, t0, root0);
  if (started.clamped) log::warn("start parameter {} clamped to {}", p0, started.applied);
  if (script && !script->path.empty()) {
    controller_.follow(&path_);
    following_ = true;
    if (start == locomotion_) speed_ = static_cast<float>(started.applied);
  } else if (start == locomotion_) {
    speed_ = static_cast<float>(started.applied);
    controller_.walk(speed_, heading_);
  }
  const int jump = graph.find_space(ControllerOptions{}.jump_space);
  if (jump >= 0) jump_length_ = space_parameter_[jump];
  if (jump_height_space_ >= 0) jump_height_ = space_parameter_[jump_height_space_];

  const MotionSpace& m = graph.spaces.front().motion;
  renderer_.set_mesh(m.triangles, m.blend.num_vertices);
  // Key textures, when the asset carries them, are uploaded here once; an asset without them is
  // shaded from the blended normals.
  const AssetTextures& textures = graph.textures;
  if (!textures.empty()) {
    std::vector<const std::uint8_t*> images;
    for (const cv::Mat& image : textures.images) images.push_back(image.ptr<std::uint8_t>());
    renderer_.upload_key_textures(textures.width, textures.height, images, textures.corner_uvs);
    log::info("{}: {} key textures of {}x{}, blended on the GPU", options.asset.string(),
              textures.images.size(), textures.width, textures.height);
  } else {
    log::info("{}: no key textures in the asset: shading from the blended normals",
              options.asset.string());
  }
  camera_.mode = options.camera;
  camera_.distance = options.camera_distance;
  lines_.reserve(4096);
  points_.reserve(256);
  character_.step(0);
}

void App::frame(double dt, double frame_seconds) {
  frame_ms_[frame_index_ % kFrameHistory] = static_cast<float>(1e3 * frame_seconds);
  ++frame_index_;
  const int n = std::min(frame_index_, kFrameHistory);
  float sum = 0;
  for (int k = 0; k < n; ++k) sum += frame_ms_[k];
  mean_ms_ = sum / n;

  ImGui_ImplOpenGL3_NewFrame();
  ImGui_ImplGlfw_NewFrame();
  ImGui::NewFrame();
  handle_input(dt);

  const double step = paused_ ? 0.0 : dt * time_scale_;
  // A script's events up to this frame, each at its own motion time (as fourd-play plays them).
  const double frame_time = character_.time() + step;
  while (script_ && step > 0 && next_event_ < script_->events.size() &&
         script_->events[next_event_].time <= frame_time + 1e-12) {
    const ScriptEvent& e = script_->events[next_event_++];
    character_.step(std::max(e.time - character_.time(), 0.0));
    play_event(e);
  }
  const CharacterFrame& out = character_.step(std::max(frame_time - character_.time(), 0.0));
  if (walk_pending_) apply_walk();
  renderer_.update_character(out);
  if (renderer_.textured()) {
    const auto count = static_cast<std::size_t>(out.textures.count);
    renderer_.set_key_blend({out.textures.images.data(), count},
                            {out.textures.weights.data(), count});
  }
  if (following_ && controller_.follow_status().done) following_ = false;

  const Point2 root{out.root.x, out.root.y};
  const int last = (trail_next_ + kTrail - 1) % kTrail;
  if (trail_count_ == 0 ||
      std::hypot(root.x - trail_[last].x, root.y - trail_[last].y) > 0.02) {
    trail_[trail_next_] = root;
    trail_next_ = (trail_next_ + 1) % kTrail;
    trail_count_ = std::min(trail_count_ + 1, kTrail);
  }
  if (camera_.mode == CameraMode::kFollow) camera_.follow(out.root.x, out.root.y, out.root.heading, dt);

  glfwGetFramebufferSize(window_, &width_, &height_);
  draw_scene(width_, height_);
  if (options_.show_ui) draw_ui();
  ImGui::Render();
  ImGui_ImplOpenGL3_RenderDrawData(ImGui::GetDrawData());
}

void App::handle_input(double dt) {
  const ImGuiIO& io = ImGui::GetIO();
  if (!io.WantCaptureKeyboard) {
    const float speed_rate = 0.8f, turn_rate = static_cast<float>(90 * kDeg);
    auto down = [&](int a, int b) { return ImGui::IsKeyDown(a) || ImGui::IsKeyDown(b); };
    if (locomotion_ >= 0) {
      const GraphSpace& loco = space(locomotion_);
      float speed = speed_, heading = heading_;
      if (down(GLFW_KEY_UP, GLFW_KEY_W)) speed += speed_rate * static_cast<float>(dt);
      if (down(GLFW_KEY_DOWN, GLFW_KEY_S)) speed -= speed_rate * static_cast<float>(dt);
      if (down(GLFW_KEY_LEFT, GLFW_KEY_A)) heading += turn_rate * static_cast<float>(dt);
      if (down(GLFW_KEY_RIGHT, GLFW_KEY_D)) heading -= turn_rate * static_cast<float>(dt);
      speed = std::clamp(speed, static_cast<float>(loco.parameter_min()),
                         static_cast<float>(loco.parameter_max()));
      if (speed != speed_ || heading != heading_) {
        speed_ = speed;
        heading_ = heading;
        walk_pending_ = true;
      }
    }
    if (ImGui::IsKeyPressed(GLFW_KEY_SPACE, false)) {
      request_status(controller_.jump(jump_length_), fmt::format("jump {:.2f} m", jump_length_),
                     asset_.graph.find_space(ControllerOptions{}.jump_space));
    }
    if (ImGui::IsKeyPressed(GLFW_KEY_H, false) && jump_height_space_ >= 0) {
      request(jump_height_space_, jump_height_, "jump height");
    }
    if (ImGui::IsKeyPressed(GLFW_KEY_R, false)) {
      const Eigen::Vector3f t = reach_world();
      request_status(controller_.reach(t.x(), t.y(), t.z()), "reach",
                     asset_.graph.find_space(ControllerOptions{}.reach_space));
    }
    if (ImGui::IsKeyPressed(GLFW_KEY_P, false)) {
      click_mode_ = click_mode_ == ClickMode::kPathPoint ? ClickMode::kWalkTowards
                                                         : ClickMode::kPathPoint;
    }
    if (ImGui::IsKeyPressed(GLFW_KEY_ENTER, false)) follow_path();
    if (ImGui::IsKeyPressed(GLFW_KEY_BACKSPACE, false) && !path_points_.empty()) {
      path_points_.pop_back();
    }
    if (ImGui::IsKeyPressed(GLFW_KEY_C, false)) {
      camera_.mode = camera_.mode == CameraMode::kFollow ? CameraMode::kOrbit : CameraMode::kFollow;
      if (camera_.mode == CameraMode::kOrbit) camera_.yaw = camera_.world_yaw();
      else camera_.yaw -= camera_.follow_heading;
    }
    if (ImGui::IsKeyPressed(GLFW_KEY_F, false)) {
      const RootTransform& r = character_.frame().root;
      camera_.target = {static_cast<float>(r.x), static_cast<float>(r.y), camera_.target_height};
    }
  }
  if (!io.WantCaptureMouse) {
    if (ImGui::IsMouseDragging(ImGuiMouseButton_Left, 3) ||
        ImGui::IsMouseDragging(ImGuiMouseButton_Right, 3)) {
      camera_.rotate(io.MouseDelta.x, io.MouseDelta.y);
      mouse_dragged_ = true;
    }
    if (io.MouseWheel != 0) camera_.zoom(io.MouseWheel);
    if (ImGui::IsMouseReleased(ImGuiMouseButton_Left) && !mouse_dragged_) {
      ground_click(io.MousePos.x * io.DisplayFramebufferScale.x,
                   io.MousePos.y * io.DisplayFramebufferScale.y);
    }
  }
  if (!ImGui::IsMouseDown(ImGuiMouseButton_Left) && !ImGui::IsMouseDown(ImGuiMouseButton_Right)) {
    mouse_dragged_ = false;
  }
}

void App::ground_click(float x, float y) {
  Point2 p;
  if (!pick_ground(view_, projection_, x, y, width_, height_, &p)) return;
  const RootTransform& r = character_.frame().root;
  switch (click_mode_) {
    case ClickMode::kWalkTowards:
      heading_ = static_cast<float>(std::atan2(p.y - r.y, p.x - r.x));
      // Keep the heading continuous with the current one (the controller steers the short way).
      heading_ = static_cast<float>(r.heading + wrap_heading(heading_ - r.heading));
      walk_pending_ = true;
      break;
    case ClickMode::kPathPoint:
      if (path_points_.empty() || following_) {
        path_points_.assign(1, Point2{r.x, r.y});
        following_ = false;
      }
      path_points_.push_back(p);
      break;
    case ClickMode::kReachTarget: {
      // The clicked point becomes the target, at the chosen height, relative to the character.
      const double c = std::cos(r.heading), s = std::sin(r.heading);
      const double dx = p.x - r.x, dy = p.y - r.y;
      reach_offset_[0] = static_cast<float>(c * dx + s * dy);
      reach_offset_[1] = static_cast<float>(-s * dx + c * dy);
      const Eigen::Vector3f t = reach_world();
      request_status(controller_.reach(t.x(), t.y(), t.z()), "reach",
                     asset_.graph.find_space(ControllerOptions{}.reach_space));
      break;
    }
  }
}

void App::apply_walk() {
  // A speed or heading change waits while a one-shot motion or a transition plays, so holding a
  // key does not cut a jump short.
  const CharacterState& s = character_.state();
  if (locomotion_ < 0 || s.space != locomotion_ || s.phase != PlayPhase::kFree) return;
  walk_pending_ = false;
  following_ = false;
  controller_.walk(speed_, heading_);
}

void App::request(int target, double p, const char* what) {
  request_status(character_.request_motion(target, p), fmt::format("{} {:.2f}", what, p), target);
}

void App::request_status(const RequestStatus& status, const std::string& what, int target) {
  const int from = character_.state().space;
  request_text_ = fmt::format("{}: {}", what, request_result_name(status.result));
  if (status.clamped) request_text_ += fmt::format(" (clamped to {:.2f})", status.applied);
  route_.assign(1, from);
  request_time_ = character_.time();
  request_one_shot_ = false;
  if (target < 0 || status.result == RequestResult::kNoRoute ||
      status.result == RequestResult::kUnknownSpace) {
    route_.clear();
    return;
  }
  if (target != from) {
    const std::vector<int> route = shortest_route(asset_.graph, from, target);
    route_.insert(route_.end(), route.begin(), route.end());
  }
  request_one_shot_ = !space(target).cyclic();
  if (status.result != RequestResult::kUnknownSpace && target != locomotion_) following_ = false;
}

void App::follow_path() {
  std::vector<BezierCurve> curves = bezier_through(path_points_);
  if (curves.empty()) {
    request_text_ = "path: click at least one point on the ground first";
    return;
  }
  if (locomotion_ >= 0) {
    for (BezierCurve& c : curves) c.speed = -1;
    curves.front().speed = speed_;
  }
  path_ = GroundPath(std::move(curves));
  controller_.follow(&path_);
  following_ = true;
  walk_pending_ = false;
  request_text_ = fmt::format("follow a path of {} curves, {:.2f} m", path_.curves().size(),
                              path_.length());
  route_.clear();
}

void App::play_event(const ScriptEvent& e) {
  const std::string what = fmt::format("{}:{}", script_->name, e.line);
  switch (e.command) {
    case ScriptCommand::kParam:
      request_status(character_.set_parameters(e.a), what + " param", character_.state().space);
      break;
    case ScriptCommand::kMotion: {
      const int target = asset_.graph.find_space(e.space);
      request_status(character_.request_motion(target, e.a, e.b), what + " " + e.space, target);
      break;
    }
    case ScriptCommand::kTurn:
      character_.set_turn_rate(e.a * kDeg);
      break;
    case ScriptCommand::kWalk:
      speed_ = static_cast<float>(e.a);
      heading_ = static_cast<float>(e.b * kDeg);
      following_ = false;
      walk_pending_ = false;
      request_status(controller_.walk(e.a, e.b * kDeg), what + " walk", locomotion_);
      break;
    case ScriptCommand::kJump:
      request_status(controller_.jump(e.a), what + " jump",
                     asset_.graph.find_space(ControllerOptions{}.jump_space));
      break;
    case ScriptCommand::kReach:
      following_ = false;
      request_status(controller_.reach(e.a, e.b, e.c), what + " reach",
                     asset_.graph.find_space(ControllerOptions{}.reach_space));
      break;
  }
}

Eigen::Vector3f App::reach_world() const {
  const RootTransform& r = character_.frame().root;
  const double c = std::cos(r.heading), s = std::sin(r.heading);
  return {static_cast<float>(r.x + c * reach_offset_[0] - s * reach_offset_[1]),
          static_cast<float>(r.y + s * reach_offset_[0] + c * reach_offset_[1]), reach_offset_[2]};
}

void App::draw_scene(int width, int height) {
  view_ = camera_.view();
  projection_ = camera_.projection(static_cast<float>(width) / std::max(height, 1));
  const Mat4f vp = projection_ * view_;
  renderer_.begin_frame(width, height);
  renderer_.draw_ground(vp, camera_.target.x(), camera_.target.y());

  constexpr float kLift = 0.01f;  // overlays just above the ground
  // The root's trail.
  lines_.clear();
  for (int k = 0; k < trail_count_; ++k) {
    const Point2& p = trail_[(trail_next_ - trail_count_ + k + kTrail) % kTrail];
    lines_.push_back({static_cast<float>(p.x), static_cast<float>(p.y), kLift, 0.2f, 0.35f, 0.85f});
  }
  renderer_.draw_lines(vp, lines_, true);

  // The path: curves, their control polygons and the clicked points.
  lines_.clear();
  points_.clear();
  const std::vector<BezierCurve> curves =
      following_ ? path_.curves() : bezier_through(path_points_);
  for (const BezierCurve& c : curves) {
    for (int k = 0; k < kCurveSamples; ++k) {
      const Point2 a = bezier_point(c, static_cast<double>(k) / kCurveSamples);
      const Point2 b = bezier_point(c, static_cast<double>(k + 1) / kCurveSamples);
      lines_.push_back({static_cast<float>(a.x), static_cast<float>(a.y), kLift, 1, 0.85f, 0.1f});
      lines_.push_back({static_cast<float>(b.x), static_cast<float>(b.y), kLift, 1, 0.85f, 0.1f});
    }
    for (int k = 0; k < 3; ++k) {
      const Point2& a = c.control[k];
      const Point2& b = c.control[k + 1];
      lines_.push_back({static_cast<float>(a.x), static_cast<float>(a.y), kLift, 0.6f, 0.5f, 0.3f});
      lines_.push_back({static_cast<float>(b.x), static_cast<float>(b.y), kLift, 0.6f, 0.5f, 0.3f});
    }
    for (int k = 0; k < 4; k += 3) {
      points_.push_back({static_cast<float>(c.control[k].x), static_cast<float>(c.control[k].y),
                         kLift, 0.9f, 0.2f, 0.1f});
    }
  }
  if (curves.empty()) {
    for (const Point2& p : path_points_) {
      points_.push_back({static_cast<float>(p.x), static_cast<float>(p.y), kLift, 0.9f, 0.2f, 0.1f});
    }
  }
  // The heading the walk steers to, from the root.
  const RootTransform& r = character_.frame().root;
  const float rx = static_cast<float>(r.x), ry = static_cast<float>(r.y);
  lines_.push_back({rx, ry, kLift, 0.9f, 0.9f, 0.9f});
  lines_.push_back({rx + 0.8f * std::cos(static_cast<float>(r.heading)),
                    ry + 0.8f * std::sin(static_cast<float>(r.heading)), kLift, 0.9f, 0.9f, 0.9f});
  if (!following_ && locomotion_ >= 0) {
    lines_.push_back({rx, ry, kLift, 0.2f, 0.9f, 0.9f});
    lines_.push_back({rx + 1.2f * std::cos(heading_), ry + 1.2f * std::sin(heading_), kLift, 0.2f,
                      0.9f, 0.9f});
  }
  // The reach target: a small cross in the air and its foot on the ground.
  const ReachStatus& reach = controller_.reach_status();
  if (reach.active || click_mode_ == ClickMode::kReachTarget) {
    const Eigen::Vector3f t = reach.active ? Eigen::Vector3f(static_cast<float>(reach.target[0]),
                                                             static_cast<float>(reach.target[1]),
                                                             static_cast<float>(reach.target[2]))
                                           : reach_world();
    for (int axis = 0; axis < 3; ++axis) {
      Eigen::Vector3f d = Eigen::Vector3f::Zero();
      d[axis] = 0.08f;
      const Eigen::Vector3f a = t - d, b = t + d;
      lines_.push_back({a.x(), a.y(), a.z(), 1, 0.3f, 0.6f});
      lines_.push_back({b.x(), b.y(), b.z(), 1, 0.3f, 0.6f});
    }
    lines_.push_back({t.x(), t.y(), kLift, 1, 0.3f, 0.6f});
    lines_.push_back({t.x(), t.y(), t.z(), 1, 0.3f, 0.6f});
  }
  renderer_.draw_lines(vp, lines_, false);
  renderer_.draw_points(vp, points_, 7);
  renderer_.draw_character(vp, camera_.eye());
}

void App::draw_ui() {
  draw_hud();
  draw_controls();
  draw_transition();
}

void App::draw_hud() {
  const CharacterState& s = character_.state();
  const GraphSpace& g = space(s.space);
  const RootTransform& r = character_.frame().root;
  ImGui::SetNextWindowPos(ImVec2(10, 10), ImGuiCond_Always);
  ImGui::SetNextWindowBgAlpha(0.6f);
  ImGui::Begin("HUD", nullptr,
               ImGuiWindowFlags_NoDecoration | ImGuiWindowFlags_AlwaysAutoResize |
                   ImGuiWindowFlags_NoMove | ImGuiWindowFlags_NoSavedSettings |
                   ImGuiWindowFlags_NoFocusOnAppearing | ImGuiWindowFlags_NoNav);
  ImGui::Text("%s", asset_.graph.name.c_str());
  ImGui::Text("motion   %s (%s)%s", g.name().c_str(), play_phase_name(s.phase),
              s.fading ? ", cross-fade" : "");
  ImGui::Text("%-8s %.2f -> %.2f %s", g.motion.parameter_map.parameter.c_str(), s.p, s.p_target,
              g.motion.parameter_map.unit.c_str());
  ImGui::Text("time t   %.3f   motion time %.2f s", s.t, character_.time());
  ImGui::Text("root     (%.2f, %.2f) m, heading %.0f deg", r.x, r.y,
              wrap_heading(r.heading) / kDeg);
  if (following_) {
    const FollowStatus& f = controller_.follow_status();
    ImGui::Text("path     %.2f / %.2f m, off by %.3f m", f.s, path_.length(), f.lateral_error);
  }
  ImGui::Separator();
  const float ms = mean_ms_;
  ImGui::Text("frame    %.2f ms   %.0f FPS", ms, ms > 0 ? 1e3f / ms : 0.0f);
  std::array<float, kFrameHistory> ordered{};
  const int n = std::min(frame_index_, kFrameHistory);
  for (int k = 0; k < n; ++k) {
    ordered[k] = frame_ms_[(frame_index_ - n + k + kFrameHistory) % kFrameHistory];
  }
  ImGui::PlotLines("##frame ms", ordered.data(), n, 0, "frame time [ms]", 0, 2 * ms + 1,
                   ImVec2(260, 40));
  ImGui::End();
}

void App::draw_controls() {
  const MotionGraph& graph = asset_.graph;
  ImGui::SetNextWindowPos(ImVec2(static_cast<float>(width_) - 330, 10), ImGuiCond_FirstUseEver);
  ImGui::SetNextWindowSize(ImVec2(320, 0), ImGuiCond_FirstUseEver);
  ImGui::Begin("Controls", nullptr, ImGuiWindowFlags_NoSavedSettings);
  if (locomotion_ >= 0 && ImGui::CollapsingHeader("Walk", ImGuiTreeNodeFlags_DefaultOpen)) {
    const GraphSpace& loco = space(locomotion_);
    float heading_deg = static_cast<float>(heading_ / kDeg);
    if (ImGui::SliderFloat("speed [m/s]", &speed_, static_cast<float>(loco.parameter_min()),
                           static_cast<float>(loco.parameter_max()), "%.2f")) {
      walk_pending_ = true;
    }
    if (ImGui::SliderFloat("heading [deg]", &heading_deg, -180, 180, "%.0f")) {
      heading_ = static_cast<float>(heading_deg * kDeg);
      walk_pending_ = true;
    }
    ImGui::TextDisabled("W/S or arrows: speed, A/D: turn");
  }
  if (ImGui::CollapsingHeader("Jump and reach", ImGuiTreeNodeFlags_DefaultOpen)) {
    const int jump = graph.find_space(ControllerOptions{}.jump_space);
    if (jump >= 0) {
      ImGui::SliderFloat("length [m]", &jump_length_, static_cast<float>(space(jump).parameter_min()),
                         static_cast<float>(space(jump).parameter_max()), "%.2f");
      if (ImGui::Button("Jump (space)")) {
        request_status(controller_.jump(jump_length_), fmt::format("jump {:.2f} m", jump_length_),
                       jump);
      }
    }
    if (jump_height_space_ >= 0) {
      const GraphSpace& h = space(jump_height_space_);
      ImGui::SliderFloat("height [m]", &jump_height_, static_cast<float>(h.parameter_min()),
                         static_cast<float>(h.parameter_max()), "%.2f");
      if (ImGui::Button("Jump up (H)")) request(jump_height_space_, jump_height_, "jump height");
    }
    if (controller_.has_reach()) {
      ImGui::SliderFloat3("target [m]", reach_offset_.data(), -3, 3, "%.2f");
      ImGui::TextDisabled("target: forward, left, height from the character");
      if (ImGui::Button("Reach (R)")) {
        const Eigen::Vector3f t = reach_world();
        request_status(controller_.reach(t.x(), t.y(), t.z()), "reach",
                       graph.find_space(ControllerOptions{}.reach_space));
      }
    }
  }
  if (ImGui::CollapsingHeader("Motions", ImGuiTreeNodeFlags_DefaultOpen)) {
    for (int s = 0; s < static_cast<int>(graph.spaces.size()); ++s) {
      const GraphSpace& g = space(s);
      ImGui::PushID(s);
      if (ImGui::Button(g.name().c_str(), ImVec2(110, 0))) request(s, space_parameter_[s], g.name().c_str());
      ImGui::SameLine();
      ImGui::SetNextItemWidth(120);
      ImGui::SliderFloat(g.motion.parameter_map.parameter.c_str(), &space_parameter_[s],
                         static_cast<float>(g.parameter_min()),
                         static_cast<float>(g.parameter_max()), "%.2f");
      ImGui::PopID();
    }
  }
  if (ImGui::CollapsingHeader("Ground clicks and path", ImGuiTreeNodeFlags_DefaultOpen)) {
    int mode = static_cast<int>(click_mode_);
    ImGui::RadioButton("walk towards", &mode, 0);
    ImGui::SameLine();
    ImGui::RadioButton("path (P)", &mode, 1);
    if (controller_.has_reach()) {
      ImGui::SameLine();
      ImGui::RadioButton("reach", &mode, 2);
    }
    click_mode_ = static_cast<ClickMode>(mode);
    ImGui::Text("%zu path points", path_points_.empty() ? 0 : path_points_.size() - 1);
    if (ImGui::Button("Follow (Enter)")) follow_path();
    ImGui::SameLine();
    if (ImGui::Button("Undo point")) {
      if (path_points_.size() > 1) path_points_.pop_back();
    }
    ImGui::SameLine();
    if (ImGui::Button("Clear")) {
      path_points_.clear();
      if (following_) controller_.stop_following();
      following_ = false;
    }
  }
  if (ImGui::CollapsingHeader("View", ImGuiTreeNodeFlags_DefaultOpen)) {
    int mode = camera_.mode == CameraMode::kFollow ? 0 : 1;
    ImGui::RadioButton("follow", &mode, 0);
    ImGui::SameLine();
    ImGui::RadioButton("orbit (C)", &mode, 1);
    const CameraMode wanted = mode == 0 ? CameraMode::kFollow : CameraMode::kOrbit;
    if (wanted != camera_.mode) {
      if (wanted == CameraMode::kOrbit) camera_.yaw = camera_.world_yaw();
      else camera_.yaw -= camera_.follow_heading;
      camera_.mode = wanted;
    }
    ImGui::Checkbox("pause", &paused_);
    ImGui::SameLine();
    ImGui::SetNextItemWidth(120);
    ImGui::SliderFloat("time scale", &time_scale_, 0.1f, 2, "%.1f");
    ImGui::TextDisabled("drag: orbit, wheel: zoom, F: centre orbit");
  }
  ImGui::End();
}

void App::draw_transition() {
  const TransitionRecord& r = character_.last_transition();
  if (request_text_.empty() && r.request_time < 0) return;
  const MotionGraph& graph = asset_.graph;
  ImGui::SetNextWindowPos(ImVec2(10, static_cast<float>(height_) - 190), ImGuiCond_FirstUseEver);
  ImGui::Begin("Transition", nullptr,
               ImGuiWindowFlags_AlwaysAutoResize | ImGuiWindowFlags_NoSavedSettings);
  ImGui::TextUnformatted(request_text_.empty() ? "requested by the controller (path, reach)"
                                                : request_text_.c_str());
  if (!route_.empty()) {
    std::string route;
    for (int s : route_) route += (route.empty() ? "" : " -> ") + space(s).name();
    if (request_one_shot_ && space(route_.front()).cyclic()) {
      route += " -> " + space(route_.front()).name() + " (back)";
    }
    ImGui::Text("spaces visited: %s", route.c_str());
  }
  if (r.request_time >= 0 && r.from >= 0 && r.to >= 0) {
    const TransitionPath& p = r.path;
    ImGui::Separator();
    ImGui::Text("edge %s -> %s", space(r.from).name().c_str(), space(r.to).name().c_str());
    ImGui::Text("exit  t %.2f p %.2f  ->  entry t %.2f p %.2f", p.exit.t, p.exit.p, p.entry.t,
                p.entry.p);
    ImGui::Text("planned latency %.2f s (%.1f frames), E_S %.1f, cost %.1f",
                p.latency_frames / graph.fps, p.latency_frames, p.similarity_cost, p.cost);
    const double now = character_.time();
    if (r.switch_time >= 0) {
      ImGui::Text("switched after %.2f s", r.switch_time - r.request_time);
    } else {
      ImGui::Text("switching... %.2f s", now - r.request_time);
    }
    if (r.arrive_time >= 0) {
      ImGui::Text("arrived after %.2f s (search %.0f us)", r.arrive_time - r.request_time,
                  r.search_seconds * 1e6);
    }
  }
  ImGui::End();
}

// Saves the back buffer (what was just drawn) as an image.
void save_screenshot(const std::filesystem::path& path, int width, int height) {
  cv::Mat image(height, width, CV_8UC3);
  glPixelStorei(GL_PACK_ALIGNMENT, 1);
  glReadBuffer(GL_BACK);
  glReadPixels(0, 0, width, height, GL_BGR, GL_UNSIGNED_BYTE, image.data);
  cv::flip(image, image, 0);  // OpenGL's rows go bottom to top
  write_image_atomic(path, image);
}

}  // namespace

ViewerReport run_viewer(const ViewerOptions& options) {
  options.check();
  log::Timer load_timer;
  const Asset asset = load_asset(options.asset);
  log::info("asset {}: {} motion spaces, {} edges, {} vertices, loaded in {:.2f} s",
            options.asset.string(), asset.graph.spaces.size(), asset.graph.edges.size(),
            asset.graph.num_vertices(), load_timer.seconds());
  ControlScript script;
  if (!options.script.empty()) {
    script = read_control_script(options.script);
    check_control_script(script, asset.graph);
  }
  if (!options.screenshot.empty()) {
    // Fail on an unwritable output before any frame is drawn.
    const std::filesystem::path dir = options.screenshot.parent_path();
    if (!dir.empty() && !std::filesystem::is_directory(dir)) {
      throw IoError(fmt::format("{}: the folder for the screenshot does not exist",
                                options.screenshot.string()));
    }
  }
  const bool headless = !options.screenshot.empty() || options.benchmark_seconds > 0;
  const double fixed_step =
      options.fixed_step > 0 ? options.fixed_step : (options.screenshot.empty() ? 0.0 : 1.0 / 30);

  GlfwSession glfw;
  glfwWindowHint(GLFW_CONTEXT_VERSION_MAJOR, 3);
  glfwWindowHint(GLFW_CONTEXT_VERSION_MINOR, 3);
  glfwWindowHint(GLFW_OPENGL_PROFILE, GLFW_OPENGL_CORE_PROFILE);
  glfwWindowHint(GLFW_OPENGL_FORWARD_COMPAT, GLFW_TRUE);
  glfwWindowHint(GLFW_RESIZABLE, headless ? GLFW_FALSE : GLFW_TRUE);
  const std::string title = fmt::format("fourd-view: {}", asset.graph.name);
  GlfwWindow owned(glfwCreateWindow(options.width, options.height, title.c_str(), nullptr, nullptr));
  GLFWwindow* window = owned.window;
  if (!window) throw Error("cannot open an OpenGL 3.3 core window (does the display support it?)");
  glfwMakeContextCurrent(window);
  glfwSwapInterval(options.vsync && !headless ? 1 : 0);
  log::info("OpenGL {} on {}", reinterpret_cast<const char*>(glGetString(GL_VERSION)),
            reinterpret_cast<const char*>(glGetString(GL_RENDERER)));

  ImGuiSession imgui(window);

  ViewerReport report;
  {
    App app(asset, options, options.script.empty() ? nullptr : &script, window);
    report.textured = app.textured();
    report.vertices = asset.graph.num_vertices();
    report.triangles = static_cast<int>(asset.graph.spaces.front().motion.triangles.size());
    double last = glfwGetTime();
    const double start = last;
    double frame_seconds = 0;
    while (!glfwWindowShouldClose(window)) {
      glfwPollEvents();
      const double dt = fixed_step > 0 ? fixed_step : std::min(frame_seconds, 0.1);
      app.frame(dt, frame_seconds);
      ++report.frames;
      if (!options.screenshot.empty() && report.frames == options.frames) {
        int w = 0, h = 0;
        glfwGetFramebufferSize(window, &w, &h);
        save_screenshot(options.screenshot, w, h);
        log::info("screenshot of frame {} ({}x{}) written to {}", report.frames, w, h,
                  options.screenshot.string());
      }
      glfwSwapBuffers(window);
      const double now = glfwGetTime();
      frame_seconds = now - last;
      report.max_frame_ms = std::max(report.max_frame_ms, 1e3 * frame_seconds);
      last = now;
      const bool screenshot_done = !options.screenshot.empty() && report.frames >= options.frames;
      const bool benchmark_done =
          options.benchmark_seconds > 0 && now - start >= options.benchmark_seconds;
      if ((screenshot_done && options.benchmark_seconds <= 0) || benchmark_done) break;
    }
    report.seconds = glfwGetTime() - start;
  }
  report.fps = report.seconds > 0 ? report.frames / report.seconds : 0;
  report.mean_frame_ms = report.frames > 0 ? 1e3 * report.seconds / report.frames : 0;
  return report;
}

}  // namespace fourd::viewer
