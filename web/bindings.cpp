// The JavaScript API of the web player's module (fourd_web.js; docs/web.md): one player at a
// time, loaded from a file of Emscripten's in-memory file system. Functions that can fail return
// an error message ("" on success) or JSON with an "error" key: exceptions do not cross into
// JavaScript. Arrays are views into the module's memory, valid until the next call that
// allocates (the page copies or uploads them at once).
#include <emscripten/bind.h>
#include <emscripten/val.h>

#include <exception>
#include <memory>
#include <nlohmann/json.hpp>
#include <string>

#include "web/web_player.h"

namespace {

using emscripten::typed_memory_view;
using emscripten::val;
using fourd::web::WebPlayer;

std::unique_ptr<WebPlayer> player;

std::string error_json(const std::exception& e) { return nlohmann::json{{"error", e.what()}}.dump(); }

std::string load(const std::string& path) {
  try {
    player.reset();
    player = std::make_unique<WebPlayer>(path);
    return "";
  } catch (const std::exception& e) {
    return e.what();
  }
}

std::string info() { return player ? player->info_json() : "{}"; }

val triangles() {
  const auto& t = player->triangle_indices();
  return val(typed_memory_view(t.size(), t.data()));
}
val corner_uvs() {
  const auto& uv = player->corner_uvs();
  return val(typed_memory_view(uv.size(), uv.data()));
}
// The JPEG file of key texture k (the browser decodes it).
val texture_file(int k) {
  const auto& images = player->asset().graph.textures.images;
  if (k < 0 || k >= static_cast<int>(images.size())) return val::null();
  return val(typed_memory_view(images[k].size(), images[k].data()));
}

double frame(double dt, int keys) { return player->frame(dt, keys); }

// Positions then normals of the shown frame (root frame, planes x | y | z of plane_stride).
val positions() {
  const auto& f = player->shown().positions;
  return val(typed_memory_view(f.data.size(), f.data.data()));
}
val normals() {
  const auto& f = player->shown().normals;
  return val(typed_memory_view(f.data.size(), f.data.data()));
}
// x, y, heading of the shown frame's root.
val root() {
  static double r[3];
  const auto& root = player->shown().root;
  r[0] = root.x;
  r[1] = root.y;
  r[2] = root.heading;
  return val(typed_memory_view(3, r));
}
// The key textures to blend: layers and weights (count entries each).
val texture_layers() {
  const auto& t = player->shown().textures;
  return val(typed_memory_view(static_cast<std::size_t>(t.count), t.images.data()));
}
val texture_weights() {
  const auto& t = player->shown().textures;
  return val(typed_memory_view(static_cast<std::size_t>(t.count), t.weights.data()));
}
val view_projection() { return val(typed_memory_view(16, player->view_projection())); }
val eye() { return val(typed_memory_view(3, player->eye())); }

std::string run_script(const std::string& text, int record_every, int show_frame) {
  try {
    return player->run_script(text, record_every, show_frame).summary;
  } catch (const std::exception& e) {
    return error_json(e);
  }
}
std::string benchmark(int steps, double dt, double evict_mb) {
  const fourd::web::StepBenchmark b = fourd::web::benchmark_steps(
      player->asset(), steps, dt, 5, static_cast<std::size_t>(evict_mb * (1 << 20)));
  return nlohmann::json{{"steps", b.steps},
                        {"rounds", b.rounds},
                        {"evict_bytes", b.evict_bytes},
                        {"vertices", b.vertices},
                        {"mean_us", b.mean_us},
                        {"median_us", b.median_us},
                        {"total_ms", b.total_ms}}
      .dump();
}

}  // namespace

EMSCRIPTEN_BINDINGS(fourd_web) {
  using emscripten::function;
  function("load", &load);
  function("info", &info);
  function("triangles", &triangles);
  function("cornerUvs", &corner_uvs);
  function("textureFile", &texture_file);
  function("frame", &frame);
  function("positions", &positions);
  function("normals", &normals);
  function("root", &root);
  function("textureLayers", &texture_layers);
  function("textureWeights", &texture_weights);
  function("viewProjection", &view_projection);
  function("eye", &eye);
  function("state", +[] { return player->state_json(); });
  function("jump", +[] { player->jump(); });
  function("jumpHeight", +[] { player->jump_height(); });
  function("reach", +[] { player->reach(); });
  function("requestMotion", +[](const std::string& s, double p) { player->request_motion(s, p); });
  function("setSpeed", +[](double v) { player->set_speed(v); });
  function("setHeading", +[](double deg) { player->set_heading_deg(deg); });
  function("setJumpLength", +[](double v) { player->set_jump_length(v); });
  function("setTimeScale", +[](double v) { player->set_time_scale(v); });
  function("setPaused", +[](bool v) { player->set_paused(v); });
  function("click", +[](double x, double y, int mode) { return player->click(x, y, mode); });
  function("cameraDrag", +[](double dx, double dy) { player->camera_drag(dx, dy); });
  function("cameraZoom", +[](double steps) { player->camera_zoom(steps); });
  function("toggleCamera", +[] { player->toggle_camera_mode(); });
  function("setViewport", +[](int w, int h) { player->set_viewport(w, h); });
  function("runScript", &run_script);
  function("recordedFrames", +[] {
    const auto& r = player->run_script_result().recorded;
    return val(typed_memory_view(r.size(), r.data()));
  });
  function("recordedPositions", +[] {
    const auto& p = player->run_script_result().positions;
    return val(typed_memory_view(p.size(), p.data()));
  });
  function("showLive", +[] { player->show_live(); });
  function("benchmark", &benchmark);
}
