#pragma once
// The headless player behind `fourd-play`: plays an asset under a control script and writes
// the mesh sequence and per-frame logs.
//
// Control script: plain text, one command per line, `#` starts a comment, times in seconds of
// motion time, angles in degrees, lengths in metres:
//
//   fps 30                            output frame rate (the command line may override)
//   duration 8                        motion time to play (default: the last event + 2 s, or
//                                     until the path is done)
//   start locomotion 1.2 [T]          initial motion space, parameter, normalised time
//   at 1.0 param 1.5                  set_parameters
//   at 2.0 motion jump_length 0.9 [T] request_motion (optionally at normalised time T)
//   at 3.0 turn 20                    steer the root at 20 deg/s (0 stops)
//   at 3.0 walk 1.3 90                controller: locomotion at 1.3 m/s towards heading 90 deg
//   at 4.0 jump 1.0                   controller: a jump of 1.0 m, then back to locomotion
//   at 5.0 reach 6 -0.3 1.2           controller: walk up to world point (6, -0.3, 1.2) [m] and
//                                     reach it with the hand
//   path 0 0                          a Bezier path starting at (0, 0), followed from time 0
//   curve 1 0 2 0 3 0 [speed 1.4] [gap]   a cubic curve: two control points and its end point;
//                                     `speed` sets the locomotion speed from there on, `gap`
//                                     marks a gap to jump over
//
// A malformed line raises InputError "<script>:<line>: <reason>". Motion spaces named in the
// script are checked against the asset before anything plays.
//
// Outputs in the output folder: meshes/frame_NNNNN.ply (world coordinates, normals; every
// `mesh_every` frame), frames.csv (one row per frame: state, root, cross-fade, events, search
// time), transitions.jsonl (one JSON object per transition: request / switch / arrival times,
// latency, E_S, E_L, path, and its worst per-frame vertex step from the switch to the end of
// its cross-fade (CrossFadeWindow) against the two motions' own 99th percentile: max_vertex_step_mm,
// source_step_p99_mm, target_step_p99_mm, jump_ratio), summary.json. A FrameObserver sees every frame: fourd-play's
// --render draws them (runtime/player/render.h).
#include <filesystem>
#include <limits>
#include <string>
#include <string_view>
#include <vector>

#include "runtime/asset.h"
#include "runtime/character.h"
#include "runtime/controller.h"

namespace fourd {

enum class ScriptCommand { kParam, kMotion, kTurn, kWalk, kJump, kReach };

struct ScriptEvent {
  double time = 0;
  int line = 0;
  ScriptCommand command = ScriptCommand::kParam;
  std::string space;  // kMotion
  double a = 0;       // parameter / turn rate [deg/s] / speed / length
  double b = -1;      // kMotion: normalised time (< 0: none); kWalk: heading [deg]; kReach: y
  double c = 0;       // kReach: z
};

struct ControlScript {
  std::string name;  // for messages
  double fps = 30;
  bool has_fps = false;
  double duration = -1;  // < 0: default (see above)
  std::string start_space;
  double start_p = std::numeric_limits<double>::quiet_NaN();  // NaN: middle of the range
  double start_t = 0;
  int start_line = 0;
  std::vector<BezierCurve> path;
  int path_line = 0;
  std::vector<ScriptEvent> events;  // sorted by time, stable
};

// Throws InputError "<name>:<line>: <reason>".
ControlScript parse_control_script(std::string_view text, const std::string& name);
// Reads and parses a file (IoError when it cannot be read).
ControlScript read_control_script(const std::filesystem::path& path);
// Throws InputError naming the line of the first space the graph does not have.
void check_control_script(const ControlScript& script, const MotionGraph& graph);

// Sees every played frame (e.g. a renderer writing images: runtime/player/render.h).
struct FrameObserver {
  virtual ~FrameObserver() = default;
  // Frame `index` at motion time `time` [s]; character.frame() is the frame's output.
  virtual void on_frame(int index, double time, const Character& character) = 0;
};

struct PlayerOptions {
  std::filesystem::path out_dir;  // empty: write nothing (e.g. when an observer takes the frames)
  double fps = 0;            // > 0: overrides the script's
  double duration = -1;      // >= 0: overrides the script's
  bool write_meshes = true;
  int mesh_every = 1;        // write every n-th frame's mesh
  double max_duration = 600;  // [s] cap when following a path that never ends
  int transitions_depth = -1;  // >= 0: trellis depth instead of the asset's
  CharacterOptions character;
  ControllerOptions controller;
  FrameObserver* observer = nullptr;  // called after every frame (not owned)
};

// One played frame, for plots (world root on the ground, what was playing).
struct PlayedFrame {
  double time = 0;                   // [s]
  double x = 0, y = 0, heading = 0;  // root [m, m, rad]
  int space = 0;
  PlayPhase phase = PlayPhase::kFree;
  bool fading = false;
  double path_error = 0;  // [m] signed distance from the path (0 without one)
};

struct PlayerReport {
  int frames = 0;
  int meshes = 0;
  int transitions = 0;
  int refused = 0;
  int clamped = 0;
  double duration = 0;        // [s] motion time played
  bool followed_path = false;
  bool path_done = false;
  double path_length = 0;     // [m]
  double covered = 0;         // [m] length of the path between the root's first and last
                              // closest points (the path less arrive_distance at its end)
  double travelled = 0;       // [m] root distance while following
  double max_path_error = 0;  // [m]
  double max_search_seconds = 0;
  int jumps = 0;                   // jumps the path follower requested
  double max_abs_jump_offset = 0;  // [m] jump middle - gap middle, largest in magnitude
  int turning_requests = 0;        // requests into the turning space while following
  double root_turn_share = 0;      // part of the root's turning made by rotating the root
  ReachStatus reach;               // the last reach
  // (travelled - covered) / covered [%]: the root's path against the stretch of the path it
  // followed; 0 without a path.
  double length_error_pct() const {
    return covered > 0 ? 100 * (travelled - covered) / covered : 0.0;
  }
  std::vector<PlayedFrame> played;  // every frame
};

// Plays `script` on `asset` and writes the outputs. Logs through pipeline/core/log.h.
PlayerReport run_player(const Asset& asset, const ControlScript& script,
                        const PlayerOptions& options);

}  // namespace fourd
