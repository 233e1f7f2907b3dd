#include "web/web_player.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <nlohmann/json.hpp>
#include <numbers>

#include "pipeline/core/error.h"
#include "pipeline/core/se2.h"
#include "runtime/player.h"

namespace fourd::web {

namespace {

constexpr double kDeg = std::numbers::pi / 180;
using Clock = std::chrono::steady_clock;

double middle(const GraphSpace& g) { return 0.5 * (g.parameter_min() + g.parameter_max()); }

// The asset with its displacements decoded to float: WebAssembly has no half conversion, and
// converting on every evaluation made the blend kernel 90 % of a step (docs/web.md).
Asset load_decoded(const std::string& path) {
  Asset asset = load_asset(path);
  for (GraphSpace& space : asset.graph.spaces) space.decode_displacements();
  return asset;
}

}  // namespace

WebPlayer::WebPlayer(const std::string& asset_path)
    : asset_(load_decoded(asset_path)),
      character_(asset_.graph, asset_.transitions),
      controller_(character_) {
  const MotionGraph& graph = asset_.graph;
  const MotionSpace& m = graph.spaces.front().motion;
  triangles_.reserve(3 * m.triangles.size());
  for (const Tri& t : m.triangles) triangles_.insert(triangles_.end(), {t[0], t[1], t[2]});
  for (const Vec2f& uv : graph.textures.corner_uvs) corner_uvs_.insert(corner_uvs_.end(), {uv.x(), uv.y()});
  const ControllerOptions names;
  locomotion_ = graph.find_space(names.locomotion_space);
  jump_ = graph.find_space(names.jump_space);
  reach_ = graph.find_space(names.reach_space);
  jump_height_space_ = graph.find_space("jump_height");
  if (jump_ >= 0) jump_length_ = middle(graph.spaces[jump_]);
  if (jump_height_space_ >= 0) jump_height_ = middle(graph.spaces[jump_height_space_]);
  // As fourd-view starts: walking in the locomotion space at its middle speed, facing +x.
  const int start = locomotion_ >= 0 ? locomotion_ : 0;
  const RequestStatus started = character_.reset(start, middle(graph.spaces[start]));
  if (locomotion_ >= 0) {
    speed_ = started.applied;
    controller_.walk(speed_, heading_);
  }
  character_.step(0);
}

int WebPlayer::num_vertices() const { return asset_.graph.spaces.front().motion.blend.num_vertices; }
int WebPlayer::plane_stride() const { return blend_plane_stride(num_vertices()); }

std::string WebPlayer::info_json() const {
  const MotionGraph& g = asset_.graph;
  nlohmann::json j;
  j["name"] = g.name;
  j["fps"] = g.fps;
  j["vertices"] = num_vertices();
  j["triangles"] = triangles_.size() / 3;
  j["plane_stride"] = plane_stride();
  j["textures"] = {{"count", g.textures.images.size()},
                   {"width", g.textures.width},
                   {"height", g.textures.height}};
  for (const GraphSpace& s : g.spaces) {
    j["spaces"].push_back({{"name", s.name()},
                           {"parameter", s.motion.parameter_map.parameter},
                           {"unit", s.motion.parameter_map.unit},
                           {"min", s.parameter_min()},
                           {"max", s.parameter_max()},
                           {"cyclic", s.cyclic()}});
  }
  j["controls"] = {{"locomotion", locomotion_ >= 0}, {"jump", jump_ >= 0},
                   {"jump_height", jump_height_space_ >= 0}, {"reach", reach_ >= 0},
                   {"jump_length", jump_length_}, {"speed", speed_}};
  return j.dump();
}

double WebPlayer::frame(double dt, int keys) {
  dt = std::clamp(dt, 0.0, 0.25);  // a tab in the background must not jump seconds ahead
  if (locomotion_ >= 0) {
    // As fourd-view's keys: W/S (arrows) change the speed, A/D turn the heading.
    const GraphSpace& loco = asset_.graph.spaces[locomotion_];
    double speed = speed_, heading = heading_;
    if (keys & kFaster) speed += 0.8 * dt;
    if (keys & kSlower) speed -= 0.8 * dt;
    if (keys & kTurnLeft) heading += 90 * kDeg * dt;
    if (keys & kTurnRight) heading -= 90 * kDeg * dt;
    speed = std::clamp(speed, loco.parameter_min(), loco.parameter_max());
    if (speed != speed_ || heading != heading_) {
      speed_ = speed;
      heading_ = heading;
      walk_pending_ = true;
    }
  }
  const double step = paused_ ? 0.0 : dt * time_scale_;
  const auto t0 = Clock::now();
  const CharacterFrame& out = character_.step(step);
  step_ms_ = std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
  if (walk_pending_) apply_walk();
  if (camera_.mode == viewer::CameraMode::kFollow) {
    camera_.follow(out.root.x, out.root.y, out.root.heading, dt);
  }
  set_viewport(width_, height_);
  return step_ms_;
}

void WebPlayer::apply_walk() {
  // As fourd-view: a speed or heading change waits while a one-shot motion or a transition
  // plays, so holding a key does not cut a jump short.
  const CharacterState& s = character_.state();
  if (locomotion_ < 0 || s.space != locomotion_ || s.phase != PlayPhase::kFree) return;
  walk_pending_ = false;
  controller_.walk(speed_, heading_);
}

void WebPlayer::note(const RequestStatus& status, const std::string& what) {
  request_text_ = fmt::format("{}: {}", what, request_result_name(status.result));
  if (status.clamped) request_text_ += fmt::format(" (clamped to {:.2f})", status.applied);
}

void WebPlayer::jump() {
  note(controller_.jump(jump_length_), fmt::format("jump {:.2f} m", jump_length_));
}

void WebPlayer::jump_height() {
  if (jump_height_space_ < 0) return;
  note(character_.request_motion(jump_height_space_, jump_height_),
       fmt::format("jump height {:.2f} m", jump_height_));
}

Eigen::Vector3f WebPlayer::reach_world() const {
  const RootTransform& r = character_.frame().root;
  const double c = std::cos(r.heading), s = std::sin(r.heading);
  return {static_cast<float>(r.x + c * reach_offset_[0] - s * reach_offset_[1]),
          static_cast<float>(r.y + s * reach_offset_[0] + c * reach_offset_[1]),
          static_cast<float>(reach_offset_[2])};
}

void WebPlayer::reach() {
  const Eigen::Vector3f t = reach_world();
  note(controller_.reach(t.x(), t.y(), t.z()), "reach");
}

void WebPlayer::request_motion(const std::string& space, double p) {
  note(character_.request_motion(space, p), fmt::format("{} {:.2f}", space, p));
}

void WebPlayer::set_speed(double speed) {
  speed_ = speed;
  walk_pending_ = true;
}

void WebPlayer::set_heading_deg(double heading) {
  heading_ = heading * kDeg;
  walk_pending_ = true;
}

bool WebPlayer::click(double x, double y, int mode) {
  Point2 p;
  if (!viewer::pick_ground(view_, projection_, static_cast<float>(x), static_cast<float>(y),
                           width_, height_, &p)) {
    return false;
  }
  const RootTransform& r = character_.frame().root;
  if (mode == 1) {
    // The clicked point becomes the reach target, at the reach height, relative to the character.
    const double c = std::cos(r.heading), s = std::sin(r.heading);
    const double dx = p.x - r.x, dy = p.y - r.y;
    reach_offset_[0] = c * dx + s * dy;
    reach_offset_[1] = -s * dx + c * dy;
    reach();
    return true;
  }
  // Walk towards it; the heading continuous with the current one (the controller steers the
  // short way).
  const double heading = std::atan2(p.y - r.y, p.x - r.x);
  heading_ = r.heading + wrap_heading(heading - r.heading);
  walk_pending_ = true;
  request_text_ = fmt::format("walk towards ({:.2f}, {:.2f})", p.x, p.y);
  return true;
}

void WebPlayer::toggle_camera_mode() {
  if (camera_.mode == viewer::CameraMode::kFollow) {
    camera_.yaw = camera_.world_yaw();
    camera_.mode = viewer::CameraMode::kOrbit;
  } else {
    camera_.yaw -= camera_.follow_heading;
    camera_.mode = viewer::CameraMode::kFollow;
  }
}

void WebPlayer::set_viewport(int width, int height) {
  width_ = std::max(width, 1);
  height_ = std::max(height, 1);
  view_ = camera_.view();
  projection_ = camera_.projection(static_cast<float>(width_) / static_cast<float>(height_));
  view_projection_ = projection_ * view_;
  eye_ = camera_.eye();
}

std::string WebPlayer::state_json() const {
  const CharacterState& s = character_.state();
  const GraphSpace& g = asset_.graph.spaces[s.space];
  const RootTransform& r = shown().root;
  nlohmann::json j;
  j["motion"] = g.name();
  j["phase"] = play_phase_name(s.phase);
  j["fading"] = s.fading;
  j["parameter"] = g.motion.parameter_map.parameter;
  j["unit"] = g.motion.parameter_map.unit;
  j["p"] = s.p;
  j["p_target"] = s.p_target;
  j["t"] = s.t;
  j["time"] = character_.time();
  j["root"] = {r.x, r.y, wrap_heading(r.heading) / kDeg};
  j["speed"] = speed_;
  j["heading"] = wrap_heading(heading_) / kDeg;
  j["request"] = request_text_;
  j["step_ms"] = step_ms_;
  j["textures"] = shown().textures.count;
  j["camera"] = camera_.mode == viewer::CameraMode::kFollow ? "follow" : "orbit";
  j["script_frame"] = shown_ != nullptr;
  return j.dump();
}

namespace {

// Records the world positions of every n-th frame and keeps one frame for drawing.
class Recorder : public FrameObserver {
 public:
  Recorder(ScriptRun* run, int every, int show, CharacterFrame* kept)
      : run_(run), every_(std::max(every, 1)), show_(show), kept_(kept) {}
  void on_frame(int index, double, const Character& character) override {
    const CharacterFrame& frame = character.frame();
    if (index % every_ == 0) {
      character_world_positions(frame, &world_);
      run_->recorded.push_back(index);
      for (const Vec3f& p : world_) run_->positions.insert(run_->positions.end(), {p.x(), p.y(), p.z()});
    }
    if (index == show_) {
      *kept_ = frame;
      shown = true;
    }
  }
  bool shown = false;

 private:
  ScriptRun* run_;
  int every_, show_;
  CharacterFrame* kept_;
  std::vector<Vec3f> world_;
};

}  // namespace

const ScriptRun& WebPlayer::run_script(const std::string& text, int record_every, int show_frame) {
  const ControlScript script = parse_control_script(text, "script");
  run_ = ScriptRun{};
  Recorder recorder(&run_, record_every, show_frame, &kept_);
  PlayerOptions options;  // no out_dir: nothing written
  options.write_meshes = false;
  options.observer = &recorder;
  const PlayerReport report = run_player(asset_, script, options);
  run_.frames = report.frames;
  if (show_frame >= 0 && !recorder.shown) {
    throw InputError(fmt::format("the script plays {} frames, no frame {} to show", report.frames,
                                 show_frame));
  }
  if (recorder.shown) shown_ = &kept_;
  nlohmann::json j;
  j["frames"] = report.frames;
  j["duration_s"] = report.duration;
  j["transitions"] = report.transitions;
  j["refused_requests"] = report.refused;
  j["clamped_parameters"] = report.clamped;
  j["recorded"] = run_.recorded.size();
  run_.summary = j.dump();
  return run_;
}

}  // namespace fourd::web
