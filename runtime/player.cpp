#include "runtime/player.h"

#include <fmt/format.h>

#include <algorithm>
#include <charconv>
#include <cmath>
#include <nlohmann/json.hpp>
#include <numbers>
#include <sstream>

#include "pipeline/core/error.h"
#include "pipeline/core/files.h"
#include "pipeline/core/log.h"
#include "pipeline/core/mesh_io.h"
#include "runtime/transition_jump.h"

namespace fourd {

namespace {

constexpr double kDeg = std::numbers::pi / 180;

std::vector<std::string> split_words(std::string_view line) {
  std::vector<std::string> words;
  std::size_t i = 0;
  while (i < line.size()) {
    while (i < line.size() && std::isspace(static_cast<unsigned char>(line[i]))) ++i;
    std::size_t j = i;
    while (j < line.size() && !std::isspace(static_cast<unsigned char>(line[j]))) ++j;
    if (j > i) words.emplace_back(line.substr(i, j - i));
    i = j;
  }
  return words;
}

class LineParser {
 public:
  LineParser(const std::string& name, int line, std::vector<std::string> words)
      : name_(name), line_(line), words_(std::move(words)) {}

  [[noreturn]] void fail(const std::string& reason) const {
    throw InputError(fmt::format("{}:{}: {}", name_, line_, reason));
  }
  std::size_t size() const { return words_.size(); }
  const std::string& word(std::size_t i) const { return words_[i]; }
  double number(std::size_t i, const char* what) const {
    if (i >= words_.size()) {
      const std::string& cmd = words_[0] == "at" && words_.size() > 2 ? words_[2] : words_[0];
      fail(fmt::format("'{}' needs {}", cmd, what));
    }
    const std::string& w = words_[i];
    double v = 0;
    const auto [end, ec] = std::from_chars(w.data(), w.data() + w.size(), v);
    if (ec != std::errc() || end != w.data() + w.size() || !std::isfinite(v)) {
      fail(fmt::format("{} '{}' is not a number", what, w));
    }
    return v;
  }
  void at_most(std::size_t n) const {
    if (words_.size() > n) {
      fail(fmt::format("'{}' takes at most {} values, got {} (unexpected '{}')", words_[0], n - 1,
                       words_.size() - 1, words_[n]));
    }
  }

 private:
  const std::string& name_;
  int line_;
  std::vector<std::string> words_;
};

std::string csv_escape(const std::string& s) { return s; }  // space names have no commas

// One transition as a JSON line; times < 0 (null) when it was replaced before it got there.
// `worst_step`: the largest per-frame vertex displacement from the request to the end of the
// transition (its cross-fade included) [m], frames `frame_seconds` apart.
std::string transition_json(const MotionGraph& graph, const TransitionOptions& search,
                            const TransitionRecord& r, double worst_step, double frame_seconds) {
  const TransitionPath& path = r.path;
  auto time = [](double t) { return t >= 0 ? nlohmann::json(t) : nlohmann::json(nullptr); };
  nlohmann::json j;
  j["from"] = graph.spaces[r.from].name();
  j["to"] = graph.spaces[r.to].name();
  j["request_time_s"] = r.request_time;
  j["switch_time_s"] = time(r.switch_time);
  j["arrive_time_s"] = time(r.arrive_time);
  j["completed"] = r.arrive_time >= 0;
  j["switch_latency_s"] = time(r.switch_time >= 0 ? r.switch_time - r.request_time : -1);
  j["latency_s"] = time(r.arrive_time >= 0 ? r.arrive_time - r.request_time : -1);
  j["path_latency_frames"] = path.latency_frames;
  j["path_latency_s"] = path.latency_frames / graph.fps;
  j["similarity_cost"] = path.similarity_cost;
  j["latency_cost"] = search.lambda * path.latency_frames;
  j["cost"] = path.cost;
  j["similarity_lower_bound"] = path.similarity;
  j["exit"] = {{"t", path.exit.t}, {"p", path.exit.p}};
  j["entry"] = {{"t", path.entry.t}, {"p", path.entry.p}};
  j["end"] = {{"t", path.end.t}, {"p", path.end.p}};
  j["search_us"] = r.search_seconds * 1e6;
  j["candidates"] = path.candidates;
  // The lurch: the worst vertex step against the two motions' own (99th percentile).
  const double source = motion_displacement_p99(graph, r.from, path.start.p, frame_seconds);
  const double target = motion_displacement_p99(graph, r.to, path.end.p, frame_seconds);
  const double reference = std::max(source, target);
  j["max_vertex_step_mm"] = 1000 * worst_step;
  j["source_step_p99_mm"] = 1000 * source;
  j["target_step_p99_mm"] = 1000 * target;
  j["jump_ratio"] = reference > 0 ? worst_step / reference : 0.0;
  return j.dump();
}

}  // namespace

ControlScript parse_control_script(std::string_view text, const std::string& name) {
  ControlScript script;
  script.name = name;
  std::istringstream in{std::string(text)};
  std::string raw;
  int line = 0;
  bool path_open = false;
  Point2 path_end;
  while (std::getline(in, raw)) {
    ++line;
    const std::size_t hash = raw.find('#');
    if (hash != std::string::npos) raw.resize(hash);
    std::vector<std::string> words = split_words(raw);
    if (words.empty()) continue;
    const LineParser p(script.name, line, words);
    const std::string& cmd = words[0];
    if (cmd == "fps") {
      p.at_most(2);
      script.fps = p.number(1, "a frame rate");
      if (!(script.fps > 0 && script.fps <= 1000)) p.fail("fps must lie in (0, 1000]");
      script.has_fps = true;
    } else if (cmd == "duration") {
      p.at_most(2);
      script.duration = p.number(1, "a duration in seconds");
      if (script.duration < 0) p.fail("duration must be >= 0");
    } else if (cmd == "start") {
      p.at_most(4);
      if (p.size() < 2) p.fail("'start' needs a motion space name");
      if (!script.start_space.empty()) p.fail(fmt::format("second 'start' (the first is on line {})", script.start_line));
      script.start_space = words[1];
      if (p.size() > 2) script.start_p = p.number(2, "a parameter");
      if (p.size() > 3) {
        script.start_t = p.number(3, "a normalised time");
        if (script.start_t < 0 || script.start_t > 1) p.fail("start time must lie in [0, 1]");
      }
      script.start_line = line;
    } else if (cmd == "at") {
      ScriptEvent e;
      e.line = line;
      e.time = p.number(1, "a time in seconds");
      if (e.time < 0) p.fail("event time must be >= 0");
      if (p.size() < 3) p.fail("'at' needs a command (param, motion, turn, walk, jump, reach)");
      const std::string& what = words[2];
      if (what == "param") {
        p.at_most(4);
        e.command = ScriptCommand::kParam;
        e.a = p.number(3, "a parameter value");
      } else if (what == "motion") {
        p.at_most(6);
        e.command = ScriptCommand::kMotion;
        if (p.size() < 4) p.fail("'motion' needs a motion space name");
        e.space = words[3];
        e.a = p.number(4, "a parameter value");
        if (p.size() > 5) {
          e.b = p.number(5, "a normalised time");
          if (e.b < 0 || e.b > 1) p.fail("motion time must lie in [0, 1]");
        }
      } else if (what == "turn") {
        p.at_most(4);
        e.command = ScriptCommand::kTurn;
        e.a = p.number(3, "a turn rate in deg/s");
      } else if (what == "walk") {
        p.at_most(5);
        e.command = ScriptCommand::kWalk;
        e.a = p.number(3, "a speed");
        e.b = p.number(4, "a heading in degrees");
      } else if (what == "jump") {
        p.at_most(4);
        e.command = ScriptCommand::kJump;
        e.a = p.number(3, "a jump length");
      } else if (what == "reach") {
        p.at_most(6);
        e.command = ScriptCommand::kReach;
        e.a = p.number(3, "a target x y z");
        e.b = p.number(4, "a target x y z");
        e.c = p.number(5, "a target x y z");
      } else {
        p.fail(fmt::format(
            "unknown command '{}' (expected param, motion, turn, walk, jump or reach)", what));
      }
      script.events.push_back(e);
    } else if (cmd == "path") {
      p.at_most(3);
      if (path_open) p.fail(fmt::format("second 'path' (the first is on line {})", script.path_line));
      path_end = {p.number(1, "a start x"), p.number(2, "a start y")};
      path_open = true;
      script.path_line = line;
    } else if (cmd == "curve") {
      if (!path_open) p.fail("'curve' before 'path'");
      BezierCurve c;
      c.control[0] = path_end;
      for (int k = 1; k <= 3; ++k) {
        c.control[k] = {p.number(2 * k - 1, "six coordinates"), p.number(2 * k, "six coordinates")};
      }
      for (std::size_t i = 7; i < p.size(); ++i) {
        if (words[i] == "speed") {
          c.speed = p.number(++i, "a speed after 'speed'");
          if (c.speed < 0) p.fail("speed must be >= 0");
        } else if (words[i] == "gap") {
          c.gap = true;
        } else {
          p.fail(fmt::format("unexpected '{}' (expected 'speed V' or 'gap')", words[i]));
        }
      }
      path_end = c.control[3];
      script.path.push_back(c);
    } else {
      p.fail(fmt::format("unknown command '{}' (expected fps, duration, start, at, path, curve)", cmd));
    }
  }
  if (script.start_space.empty()) {
    throw InputError(fmt::format("{}: no 'start <space> [parameter] [time]' line", script.name));
  }
  if (path_open && script.path.empty()) {
    throw InputError(fmt::format("{}:{}: 'path' without any 'curve'", script.name, script.path_line));
  }
  if (!script.path.empty()) {
    try {
      GroundPath check(script.path);
    } catch (const InputError& e) {
      throw InputError(fmt::format("{}:{}: {}", script.name, script.path_line, e.what()));
    }
  }
  std::stable_sort(script.events.begin(), script.events.end(),
                   [](const ScriptEvent& a, const ScriptEvent& b) { return a.time < b.time; });
  return script;
}

ControlScript read_control_script(const std::filesystem::path& path) {
  return parse_control_script(read_file(path), path.string());
}

void check_control_script(const ControlScript& script, const MotionGraph& graph) {
  auto names = [&] {
    std::string s;
    for (const GraphSpace& g : graph.spaces) s += (s.empty() ? "" : ", ") + g.name();
    return s;
  };
  if (graph.find_space(script.start_space) < 0) {
    throw InputError(fmt::format("{}:{}: unknown motion space '{}' (the asset has: {})",
                                 script.name, script.start_line, script.start_space, names()));
  }
  for (const ScriptEvent& e : script.events) {
    if (e.command == ScriptCommand::kMotion && graph.find_space(e.space) < 0) {
      throw InputError(fmt::format("{}:{}: unknown motion space '{}' (the asset has: {})",
                                   script.name, e.line, e.space, names()));
    }
  }
}

PlayerReport run_player(const Asset& asset, const ControlScript& script,
                        const PlayerOptions& options) {
  const MotionGraph& graph = asset.graph;
  check_control_script(script, graph);
  if (options.mesh_every < 1) throw ConfigError("mesh_every must be >= 1");
  const double fps = options.fps > 0 ? options.fps : script.fps;
  if (!(fps > 0 && fps <= 1000)) throw ConfigError(fmt::format("fps {} must lie in (0, 1000]", fps));

  TransitionOptions search = asset.transitions;
  if (options.transitions_depth >= 0) search.depth = options.transitions_depth;
  Character character(graph, search, options.character);
  Controller controller(character, options.controller);
  const int start = graph.find_space(script.start_space);
  const GraphSpace& s0 = graph.spaces[start];
  const double p0 = std::isnan(script.start_p) ? 0.5 * (s0.parameter_min() + s0.parameter_max())
                                               : script.start_p;
  PlayerReport report;
  GroundPath path;
  if (!script.path.empty()) {
    path = GroundPath(script.path);
    report.followed_path = true;
    report.path_length = path.length();
  }
  // Start on the path, facing along it.
  RootTransform root;
  if (report.followed_path) {
    const Point2 a = path.point_at(0);
    root = {a.x, a.y, path.heading_at(0)};
  }
  const RequestStatus started = character.reset(start, p0, script.start_t, root);
  if (started.clamped) {
    log::warn("{}:{}: start parameter {} clamped to {}", script.name, script.start_line, p0,
              started.applied);
  }
  if (report.followed_path) controller.follow(&path);

  double duration = options.duration >= 0 ? options.duration : script.duration;
  if (duration < 0) {
    duration = report.followed_path ? options.max_duration
                                    : (script.events.empty() ? 0.0 : script.events.back().time) + 2;
  }
  duration = std::min(duration, options.max_duration);
  const int frames = static_cast<int>(std::floor(duration * fps + 1e-9)) + 1;

  const bool write_files = !options.out_dir.empty();
  const bool write_meshes = write_files && options.write_meshes;
  const std::filesystem::path mesh_dir = options.out_dir / "meshes";
  if (write_files) ensure_directory(options.out_dir);
  if (write_meshes) ensure_directory(mesh_dir);
  std::string csv =
      "frame,time,space,t,p,p_target,phase,fading,fade_weight,root_x,root_y,heading,turn_rate,"
      "searches,switches,arrivals,refused,search_us,path_s,path_error,event\n";
  std::string transitions;
  Mesh mesh;
  mesh.triangles = graph.spaces.front().motion.triangles;

  std::size_t next_event = 0;
  double last_switch = -1, written_request = -1;
  TransitionRecord open;  // the transition being played, not yet written
  double open_step = 0;   // its worst per-frame vertex step so far [m]
  VertexJumpMeter jump_meter;
  log::info("playing {:.2f} s at {} fps ({} frames), {} events{}", duration, fps, frames,
            script.events.size(), report.followed_path ? ", following a path" : "");
  for (int f = 0; f < frames; ++f) {
    const double frame_time = f / fps;
    std::string event_text;
    StepEvents events;
    // Events up to this frame's time, each at its own time.
    while (next_event < script.events.size() && script.events[next_event].time <= frame_time + 1e-12) {
      const ScriptEvent& e = script.events[next_event++];
      character.step(e.time - character.time());
      events.searches += character.events().searches;
      events.switches += character.events().switches;
      events.arrivals += character.events().arrivals;
      events.refused += character.events().refused;
      events.search_seconds += character.events().search_seconds;
      RequestStatus status;
      std::string what;
      switch (e.command) {
        case ScriptCommand::kParam:
          status = character.set_parameters(e.a);
          what = fmt::format("param {}", e.a);
          break;
        case ScriptCommand::kMotion:
          status = character.request_motion(e.space, e.a, e.b);
          what = fmt::format("motion {} {}", e.space, e.a);
          break;
        case ScriptCommand::kTurn:
          character.set_turn_rate(e.a * kDeg);
          what = fmt::format("turn {}", e.a);
          break;
        case ScriptCommand::kWalk:
          status = controller.walk(e.a, e.b * kDeg);
          what = fmt::format("walk {} {}", e.a, e.b);
          break;
        case ScriptCommand::kJump:
          status = controller.jump(e.a);
          what = fmt::format("jump {}", e.a);
          break;
        case ScriptCommand::kReach:
          status = controller.reach(e.a, e.b, e.c);
          what = fmt::format("reach {} {} {}", e.a, e.b, e.c);
          break;
      }
      if (status.clamped) {
        ++report.clamped;
        log::warn("{}:{}: {}: parameter clamped to {}", script.name, e.line, what, status.applied);
        what += fmt::format(" (clamped to {})", status.applied);
      }
      if (status.result == RequestResult::kNoRoute || status.result == RequestResult::kUnknownSpace) {
        ++report.refused;
        log::warn("{}:{}: {}: refused ({})", script.name, e.line, what,
                  request_result_name(status.result));
        what += fmt::format(" (refused: {})", request_result_name(status.result));
      } else if (status.result == RequestResult::kRouted) {
        what += fmt::format(" (routed, {} hops)", status.hops);
      }
      event_text += (event_text.empty() ? "" : "; ") + what;
    }
    character.step(frame_time - character.time());
    events.searches += character.events().searches;
    events.switches += character.events().switches;
    events.arrivals += character.events().arrivals;
    events.refused += character.events().refused;
    events.search_seconds += character.events().search_seconds;
    report.max_search_seconds = std::max(report.max_search_seconds, events.search_seconds);
    report.refused += events.refused;

    // A transition is written once it arrives and its cross-fade is over, or once a newer
    // request replaces it; its worst vertex step is measured until then.
    const double step = jump_meter.add(character.frame());
    const TransitionRecord& r = character.last_transition();
    if (open.request_time >= 0 && r.request_time != open.request_time) {
      transitions += transition_json(graph, search, open, open_step, 1 / fps) + "\n";
      ++report.transitions;
      open = TransitionRecord{};
    }
    if (r.request_time >= 0 && r.request_time != written_request) {
      if (open.request_time != r.request_time) open_step = 0;
      open = r;
      open_step = std::max(open_step, step);
      if (r.arrive_time >= 0 && !character.state().fading) {
        transitions += transition_json(graph, search, open, open_step, 1 / fps) + "\n";
        ++report.transitions;
        written_request = r.request_time;
        open = TransitionRecord{};
      }
    }
    if (r.switch_time >= 0 && r.switch_time != last_switch) {
      last_switch = r.switch_time;
      event_text += fmt::format("{}switch {} -> {}", event_text.empty() ? "" : "; ",
                                graph.spaces[r.from].name(), graph.spaces[r.to].name());
    }

    const CharacterState& s = character.state();
    const CharacterFrame& out = character.frame();
    const FollowStatus& follow = controller.follow_status();
    csv += fmt::format("{},{:.6f},{},{:.6f},{:.6f},{:.6f},{},{},{:.4f},{:.6f},{:.6f},{:.6f},{:.6f},"
                       "{},{},{},{},{:.2f},{:.4f},{:.4f},{}\n",
                       f, frame_time, csv_escape(graph.spaces[s.space].name()), s.t, s.p,
                       s.p_target, play_phase_name(s.phase), s.fading ? 1 : 0, out.fade_weight,
                       out.root.x, out.root.y, out.root.heading, s.turn_rate, events.searches,
                       events.switches, events.arrivals, events.refused,
                       events.search_seconds * 1e6, follow.s, follow.lateral_error, event_text);
    if (write_meshes && f % options.mesh_every == 0) {
      character_world_positions(out, &mesh.positions);
      character_world_normals(out, &mesh.normals);
      write_ply(mesh_dir / fmt::format("frame_{:05d}.ply", f), mesh);
      ++report.meshes;
    }
    if (options.observer) options.observer->on_frame(f, frame_time, character);
    report.played.push_back({frame_time, out.root.x, out.root.y, out.root.heading, s.space, s.phase,
                             s.fading, follow.lateral_error});
    report.frames = f + 1;
    report.duration = frame_time;
    if (report.followed_path && follow.done && options.duration < 0 && script.duration < 0) break;
  }
  if (open.request_time >= 0) {
    transitions += transition_json(graph, search, open, open_step, 1 / fps) + "\n";
    ++report.transitions;
  }
  const FollowStatus& follow = controller.follow_status();
  report.path_done = follow.done;
  report.travelled = follow.travelled;
  report.covered = follow.s - follow.s_start;
  report.max_path_error = follow.max_abs_error;
  report.jumps = follow.jumps;
  report.max_abs_jump_offset = follow.max_abs_jump_offset;
  report.turning_requests = follow.turning_requests;
  report.root_turn_share = follow.total_turn > 0 ? follow.root_turn / follow.total_turn : 0.0;
  report.reach = controller.reach_status();
  report.clamped = character.clamp_count();

  if (!write_files) return report;
  write_file_atomic(options.out_dir / "frames.csv", csv);
  write_file_atomic(options.out_dir / "transitions.jsonl", transitions);
  nlohmann::json summary;
  summary["asset"] = graph.name;
  summary["script"] = script.name;
  summary["fps"] = fps;
  summary["frames"] = report.frames;
  summary["meshes"] = report.meshes;
  summary["duration_s"] = report.duration;
  summary["transitions"] = report.transitions;
  summary["refused_requests"] = report.refused;
  summary["clamped_parameters"] = report.clamped;
  summary["max_search_us"] = report.max_search_seconds * 1e6;
  if (report.followed_path) {
    summary["path"] = {{"length_m", report.path_length},
                       {"covered_m", report.covered},
                       {"done", report.path_done},
                       {"travelled_m", report.travelled},
                       {"length_error_pct", report.length_error_pct()},
                       {"max_error_m", report.max_path_error},
                       {"jumps", follow.jumps},
                       {"max_abs_jump_offset_m", report.max_abs_jump_offset},
                       {"turning_requests", report.turning_requests},
                       {"root_turn_share", report.root_turn_share}};
  }
  if (report.reach.requested || report.reach.active) {
    const ReachStatus& r = report.reach;
    summary["reach"] = {{"target", {r.target[0], r.target[1], r.target[2]}},
                        {"parameter", r.parameter},
                        {"done", r.done},
                        {"hand", {r.hand[0], r.hand[1], r.hand[2]}},
                        {"hand_error_m", r.hand_error}};
  }
  write_file_atomic(options.out_dir / "summary.json", summary.dump(2) + "\n");
  log::info("{} frames, {} meshes, {} transitions written to {}", report.frames, report.meshes,
            report.transitions, options.out_dir.string());
  return report;
}

}  // namespace fourd
