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
// `worst_step`: the largest per-frame vertex displacement from the switch to the end of the
// cross-fade (CrossFadeWindow) [m], frames `frame_seconds` apart.
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

// The step's events added to the frame's.
void add_events(StepEvents& sum, const StepEvents& e) {
  sum.searches += e.searches;
  sum.switches += e.switches;
  sum.arrivals += e.arrivals;
  sum.refused += e.refused;
  sum.search_seconds += e.search_seconds;
}

// The character put at the script's start (on the path, facing along it, when there is one).
void start_character(const ControlScript& script, const MotionGraph& graph, const GroundPath& path,
                     bool followed_path, Character& character) {
  const int start = graph.find_space(script.start_space);
  const GraphSpace& s0 = graph.spaces[start];
  const double p0 = std::isnan(script.start_p) ? 0.5 * (s0.parameter_min() + s0.parameter_max())
                                               : script.start_p;
  // Start on the path, facing along it.
  RootTransform root;
  if (followed_path) {
    const Point2 a = path.point_at(0);
    root = {a.x, a.y, path.heading_at(0)};
  }
  const RequestStatus started = character.reset(start, p0, script.start_t, root);
  if (started.clamped) {
    log::warn("{}:{}: start parameter {} clamped to {}", script.name, script.start_line, p0,
              started.applied);
  }
}

// The time played: the options', else the script's, else until the path ends or 2 s after the
// last event; at most max_duration.
double play_duration(const PlayerOptions& options, const ControlScript& script,
                     bool followed_path) {
  double duration = options.duration >= 0 ? options.duration : script.duration;
  if (duration < 0) {
    duration = followed_path ? options.max_duration
                             : (script.events.empty() ? 0.0 : script.events.back().time) + 2;
  }
  return std::min(duration, options.max_duration);
}

// The playing of a script, frame by frame: the character driven by its events, what the
// frames write (frames.csv, transitions.jsonl, meshes) and the transition being played.
class Playback {
 public:
  Playback(const MotionGraph& graph, const TransitionOptions& search, const ControlScript& script,
           const PlayerOptions& options, double fps, Character& character,
           Controller& controller, PlayerReport& report)
      : graph_(graph),
        search_(search),
        script_(script),
        options_(options),
        fps_(fps),
        character_(character),
        controller_(controller),
        report_(report),
        write_meshes_(!options.out_dir.empty() && options.write_meshes),
        mesh_dir_(options.out_dir / "meshes") {
    mesh_.triangles = graph.spaces.front().motion.triangles;
  }

  // Plays frame f: the script's events up to its time, each at its own time, then the step to
  // the frame. False: the path is done and nothing sets a duration.
  bool play_frame(int f);
  // The transition still open written, and the report's path-following figures.
  void finish();
  // frames.csv, transitions.jsonl and summary.json in out_dir.
  void write_files() const;

 private:
  std::string apply_events(double frame_time, StepEvents& events);
  std::string apply(const ScriptEvent& e);
  void track_transitions(double step, std::string& event_text);
  void write_open_transition();
  void write_frame(int f, double frame_time, const StepEvents& events,
                   const std::string& event_text);

  const MotionGraph& graph_;
  const TransitionOptions& search_;
  const ControlScript& script_;
  const PlayerOptions& options_;
  const double fps_;
  Character& character_;
  Controller& controller_;
  PlayerReport& report_;
  const bool write_meshes_;
  const std::filesystem::path mesh_dir_;
  std::string csv_ =
      "frame,time,space,t,p,p_target,phase,fading,fade_weight,root_x,root_y,heading,turn_rate,"
      "searches,switches,arrivals,refused,search_us,path_s,path_error,event\n";
  std::string transitions_;
  Mesh mesh_;
  std::size_t next_event_ = 0;
  double last_switch_ = -1, written_request_ = -1;
  TransitionRecord open_;  // the transition being played, not yet written
  double open_step_ = 0;   // its worst per-frame vertex step so far [m]
  VertexJumpMeter jump_meter_;
  CrossFadeWindow window_;
};

bool Playback::play_frame(int f) {
  const double frame_time = f / fps_;
  StepEvents events;
  std::string event_text = apply_events(frame_time, events);
  character_.step(frame_time - character_.time());
  add_events(events, character_.events());
  report_.max_search_seconds = std::max(report_.max_search_seconds, events.search_seconds);
  report_.refused += events.refused;
  track_transitions(jump_meter_.add(character_.frame()), event_text);
  write_frame(f, frame_time, events, event_text);
  const FollowStatus& follow = controller_.follow_status();
  return !(report_.followed_path && follow.done && options_.duration < 0 && script_.duration < 0);
}

// The script's events up to `frame_time`, each applied at its own time. Returns their text
// for the frame's row.
std::string Playback::apply_events(double frame_time, StepEvents& events) {
  std::string event_text;
  while (next_event_ < script_.events.size() &&
         script_.events[next_event_].time <= frame_time + 1e-12) {
    const ScriptEvent& e = script_.events[next_event_++];
    character_.step(e.time - character_.time());
    add_events(events, character_.events());
    event_text += (event_text.empty() ? "" : "; ") + apply(e);
  }
  return event_text;
}

// One event applied; returns its text, with what became of the request.
std::string Playback::apply(const ScriptEvent& e) {
  RequestStatus status;
  std::string what;
  switch (e.command) {
    case ScriptCommand::kParam:
      status = character_.set_parameters(e.a);
      what = fmt::format("param {}", e.a);
      break;
    case ScriptCommand::kMotion:
      status = character_.request_motion(e.space, e.a, e.b);
      what = fmt::format("motion {} {}", e.space, e.a);
      break;
    case ScriptCommand::kTurn:
      character_.set_turn_rate(e.a * kDeg);
      what = fmt::format("turn {}", e.a);
      break;
    case ScriptCommand::kWalk:
      status = controller_.walk(e.a, e.b * kDeg);
      what = fmt::format("walk {} {}", e.a, e.b);
      break;
    case ScriptCommand::kJump:
      status = controller_.jump(e.a);
      what = fmt::format("jump {}", e.a);
      break;
    case ScriptCommand::kReach:
      status = controller_.reach(e.a, e.b, e.c);
      what = fmt::format("reach {} {} {}", e.a, e.b, e.c);
      break;
  }
  if (status.clamped) {
    ++report_.clamped;
    log::warn("{}:{}: {}: parameter clamped to {}", script_.name, e.line, what, status.applied);
    what += fmt::format(" (clamped to {})", status.applied);
  }
  if (status.result == RequestResult::kNoRoute || status.result == RequestResult::kUnknownSpace) {
    ++report_.refused;
    log::warn("{}:{}: {}: refused ({})", script_.name, e.line, what,
              request_result_name(status.result));
    what += fmt::format(" (refused: {})", request_result_name(status.result));
  } else if (status.result == RequestResult::kRouted) {
    what += fmt::format(" (routed, {} hops)", status.hops);
  }
  return what;
}

// A transition is written once it arrives and its cross-fade is over, or once a newer request
// replaces it; its worst vertex step (`step`, this frame's) is measured until then. A switch
// is added to the frame's event text.
void Playback::track_transitions(double step, std::string& event_text) {
  const TransitionRecord& r = character_.last_transition();
  const bool in_fade = window_.counts(r, character_.state());
  if (open_.request_time >= 0 && r.request_time != open_.request_time) {
    write_open_transition();
    open_ = TransitionRecord{};
  }
  if (r.request_time >= 0 && r.request_time != written_request_) {
    if (open_.request_time != r.request_time) open_step_ = 0;
    open_ = r;
    if (in_fade) open_step_ = std::max(open_step_, step);
    if (r.arrive_time >= 0 && !character_.state().fading) {
      write_open_transition();
      written_request_ = r.request_time;
      open_ = TransitionRecord{};
    }
  }
  if (r.switch_time >= 0 && r.switch_time != last_switch_) {
    last_switch_ = r.switch_time;
    event_text += fmt::format("{}switch {} -> {}", event_text.empty() ? "" : "; ",
                              graph_.spaces[r.from].name(), graph_.spaces[r.to].name());
  }
}

void Playback::write_open_transition() {
  transitions_ += transition_json(graph_, search_, open_, open_step_, 1 / fps_) + "\n";
  ++report_.transitions;
}

// The frame's row of frames.csv, its mesh, the observer's call and the played record.
void Playback::write_frame(int f, double frame_time, const StepEvents& events,
                           const std::string& event_text) {
  const CharacterState& s = character_.state();
  const CharacterFrame& out = character_.frame();
  const FollowStatus& follow = controller_.follow_status();
  csv_ += fmt::format("{},{:.6f},{},{:.6f},{:.6f},{:.6f},{},{},{:.4f},{:.6f},{:.6f},{:.6f},{:.6f},"
                      "{},{},{},{},{:.2f},{:.4f},{:.4f},{}\n",
                      f, frame_time, csv_escape(graph_.spaces[s.space].name()), s.t, s.p,
                      s.p_target, play_phase_name(s.phase), s.fading ? 1 : 0, out.fade_weight,
                      out.root.x, out.root.y, out.root.heading, s.turn_rate, events.searches,
                      events.switches, events.arrivals, events.refused,
                      events.search_seconds * 1e6, follow.s, follow.lateral_error, event_text);
  if (write_meshes_ && f % options_.mesh_every == 0) {
    character_world_positions(out, &mesh_.positions);
    character_world_normals(out, &mesh_.normals);
    write_ply(mesh_dir_ / fmt::format("frame_{:05d}.ply", f), mesh_);
    ++report_.meshes;
  }
  if (options_.observer) options_.observer->on_frame(f, frame_time, character_);
  report_.played.push_back({frame_time, out.root.x, out.root.y, out.root.heading, s.space,
                            s.phase, s.fading, follow.lateral_error});
  report_.frames = f + 1;
  report_.duration = frame_time;
}

void Playback::finish() {
  if (open_.request_time >= 0) write_open_transition();
  const FollowStatus& follow = controller_.follow_status();
  report_.path_done = follow.done;
  report_.travelled = follow.travelled;
  report_.covered = follow.s - follow.s_start;
  report_.max_path_error = follow.max_abs_error;
  report_.jumps = follow.jumps;
  report_.max_abs_jump_offset = follow.max_abs_jump_offset;
  report_.turning_requests = follow.turning_requests;
  report_.root_turn_share = follow.total_turn > 0 ? follow.root_turn / follow.total_turn : 0.0;
  report_.reach = controller_.reach_status();
  report_.clamped = character_.clamp_count();
}

void Playback::write_files() const {
  const PlayerReport& report = report_;
  const FollowStatus& follow = controller_.follow_status();
  write_file_atomic(options_.out_dir / "frames.csv", csv_);
  write_file_atomic(options_.out_dir / "transitions.jsonl", transitions_);
  nlohmann::json summary;
  summary["asset"] = graph_.name;
  summary["script"] = script_.name;
  summary["fps"] = fps_;
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
  write_file_atomic(options_.out_dir / "summary.json", summary.dump(2) + "\n");
  log::info("{} frames, {} meshes, {} transitions written to {}", report.frames, report.meshes,
            report.transitions, options_.out_dir.string());
}

// An `at <time> <command> ...` line.
ScriptEvent parse_event(const LineParser& p, const std::vector<std::string>& words, int line) {
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
  return e;
}

// A `curve x1 y1 x2 y2 x3 y3 [speed V] [gap]` line, starting where the path ends (`start`).
BezierCurve parse_curve(const LineParser& p, const std::vector<std::string>& words,
                        const Point2& start) {
  BezierCurve c;
  c.control[0] = start;
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
  return c;
}

// A `start <space> [parameter] [time]` line.
void parse_start(const LineParser& p, const std::vector<std::string>& words, int line,
                 ControlScript& script) {
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
}

// The whole script's checks: a start, a path with curves and a valid one; the events in time
// order.
void finish_script(ControlScript& script, bool path_open) {
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
      parse_start(p, words, line, script);
    } else if (cmd == "at") {
      script.events.push_back(parse_event(p, words, line));
    } else if (cmd == "path") {
      p.at_most(3);
      if (path_open) p.fail(fmt::format("second 'path' (the first is on line {})", script.path_line));
      path_end = {p.number(1, "a start x"), p.number(2, "a start y")};
      path_open = true;
      script.path_line = line;
    } else if (cmd == "curve") {
      if (!path_open) p.fail("'curve' before 'path'");
      const BezierCurve c = parse_curve(p, words, path_end);
      path_end = c.control[3];
      script.path.push_back(c);
    } else {
      p.fail(fmt::format("unknown command '{}' (expected fps, duration, start, at, path, curve)", cmd));
    }
  }
  finish_script(script, path_open);
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
  PlayerReport report;
  GroundPath path;
  if (!script.path.empty()) {
    path = GroundPath(script.path);
    report.followed_path = true;
    report.path_length = path.length();
  }
  start_character(script, graph, path, report.followed_path, character);
  if (report.followed_path) controller.follow(&path);

  const double duration = play_duration(options, script, report.followed_path);
  const int frames = static_cast<int>(std::floor(duration * fps + 1e-9)) + 1;
  const bool write_files = !options.out_dir.empty();
  if (write_files) ensure_directory(options.out_dir);
  if (write_files && options.write_meshes) ensure_directory(options.out_dir / "meshes");
  Playback playback(graph, search, script, options, fps, character, controller, report);
  log::info("playing {:.2f} s at {} fps ({} frames), {} events{}", duration, fps, frames,
            script.events.size(), report.followed_path ? ", following a path" : "");
  for (int f = 0; f < frames; ++f) {
    if (!playback.play_frame(f)) break;
  }
  playback.finish();
  if (write_files) playback.write_files();
  return report;
}

}  // namespace fourd
