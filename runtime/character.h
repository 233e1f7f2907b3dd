#pragma once
// The runtime character: plays a 4D parametric motion graph (runtime/motion_graph.h) under
// high-level control. Per step it advances time in the current motion space, maps the
// parameter to weights (w = h^-1(p)), blends positions and the precomputed normals with the
// same coefficients (Eq. 1), integrates the root motion on the ground plane, and plays the
// transitions it is asked for along the optimal path of the online trellis search
// (runtime/transition.h).
//
// Clock. The character integrates in motion time with a fixed tick (options.tick_seconds):
// parameter ramps, the root, transitions and requests all advance tick by tick, and a frame
// that falls between two ticks is the last tick's state advanced by the remainder, without
// committing it. So a control timeline gives the same states at the same motion times whatever
// the frame rate; frames at times that are multiples of the tick are identical. A request (or a
// parameter change) made at motion time T takes effect at the first tick at or after T.
//
// Transitions. request_motion() to a space with an edge from the current one searches the
// online path at the next tick: the source plays on to the path's exit while its parameter
// ramps linearly to the exit's, then the character switches to the target at the path's entry
// and plays to the requested state, ramping the parameter likewise. The switch is hidden by a
// cross-fade (smoothstep): the source keeps playing from its exit and its shape and root
// velocity fade into the target's, so neither the shape nor the root pops. The fade lasts long
// enough that the fade itself moves no vertex faster than crossfade_speed_share of the faster
// motion's own vertex speed (its 99th percentile, measured per space at construction): 1.5 D / T <= share v for
// the largest vertex gap D between the two frames (smoothstep's steepest slope is 1.5 / T),
// T between crossfade_seconds and crossfade_max_seconds. With align_at_switch (off by default)
// the target is first aligned to the source: the ground-plane rotation and translation that
// best fit the target's shape onto the source's, which the root takes on (the body does not
// move; the root steps by the fit and keeps that small offset). Requests made while a cross-fade runs wait for its end. A request with no direct
// edge follows the shortest route through the graph (precomputed at construction), one edge at
// a time, passing through intermediate spaces at the middle of their parameter range. A one-shot
// space plays to options.one_shot_exit_t and then starts the transition to what comes next (the
// rest of a route, or back to the cyclic space it was entered from, at the parameter it played
// there). With nothing to come (the character started in it, or came from another one-shot
// space) it goes on to the graph's default successor (MotionGraph::default_successor) at the
// middle of its parameter range, so the character never freezes on the last frame; only a
// one-shot space with no way out holds its last pose.
//
// Parameters. set_parameters() sets the parameter the current motion (or the motion a
// transition is heading to) ramps to, at (p_max - p_min) per unit of normalised time, the
// trellis' own slope. Out-of-range values are clamped, and the returned status says so.
//
// Output. positions and normals in the root frame (the shapes face +x at the origin; the
// renderer applies `root`, or see character_world_positions), as planes x | y | z like
// runtime/blend.h; normals blended from the asset's per-reference normals and normalised; and,
// when the asset has textures, the key textures and weights that make the frame's texture
// (runtime/textures.h: the space's input weights and the two key phases around t, the fading
// space's too during a cross-fade).
//
// Steering. A ground-plane turn rate (set_turn_rate) rotates the root heading gradually on top
// of the motion's own root curve: the fallback for graphs without a turning space (the body
// itself does not lean into the turn).
//
// Memory. Everything is allocated at construction; step(), set_parameters(), request_motion()
// and set_turn_rate() allocate nothing. Not thread-safe; one character per thread.
#include <array>
#include <cstdint>
#include <string_view>

#include "pipeline/core/se2.h"
#include "runtime/blend.h"
#include "runtime/motion_graph.h"
#include "runtime/transition.h"

namespace fourd {

struct CharacterOptions {
  double tick_seconds = 1.0 / 240;    // [s] integration step in motion time
  double crossfade_seconds = 0.2;     // [s] shortest cross-fade at a transition's switch (0: none)
  double crossfade_max_seconds = 1.0; // [s] longest cross-fade (the fade's length adapts)
  double crossfade_speed_share = 0.4; // the fade's own vertex speed / the motions' p99, at most
  bool align_at_switch = false;       // fit the target's shape onto the source's at the switch (moves the root)
  double one_shot_exit_t = 0.75;      // normalised time at which a one-shot space plans its exit
  double max_turn_rate = 2.0;         // [rad/s] limit of set_turn_rate
  bool normalize_normals = true;      // unit normals out (else the raw blend)

  // Throws ConfigError naming the field.
  void check() const;
};

enum class RequestResult : std::uint8_t {
  kAccepted,      // searched at the next tick (direct edge, or a parameter change)
  kRouted,        // no direct edge: going through `hops` edges of the shortest route
  kNoRoute,       // no route from the current space: refused, nothing changes
  kUnknownSpace,  // no such space: refused
};
const char* request_result_name(RequestResult r);

struct RequestStatus {
  RequestResult result = RequestResult::kAccepted;
  int hops = 0;        // edges to the target (0: same space)
  double applied = 0;  // the parameter after clamping to the target space's range
  bool clamped = false;
};

enum class PlayPhase : std::uint8_t {
  kFree,    // playing the current space, the parameter ramping to its target
  kSource,  // a transition path: playing the source towards the exit
  kTarget,  // a transition path: playing the target from the entry to the requested state
};
const char* play_phase_name(PlayPhase p);

// What the character is doing: plain data, copied to evaluate a frame between ticks.
struct CharacterState {
  double time = 0;  // [s] motion time since reset
  int space = 0;
  double t = 0;         // normalised time in the space, [0, 1]
  double p = 0;         // parameter being played
  double p_target = 0;  // parameter it ramps to when free
  RootTransform root;   // world pose of the root
  double turn_rate = 0;  // [rad/s] steering on top of the root curve
  PlayPhase phase = PlayPhase::kFree;
  TransitionPath path;  // valid in kSource / kTarget
  double played = 0;    // normalised time played in the current phase of the path
  // Cross-fade from the space left at the switch.
  bool fading = false;
  int fade_space = -1;
  double fade_t = 0, fade_p = 0;
  double fade_elapsed = 0;  // [s]
  double fade_seconds = 0;  // [s] length of this cross-fade
  RootPose fade_align;      // the faded space's root frame in the current one
  // Where the character goes after the current motion: the end of a route, or back from a
  // one-shot space.
  int goal_space = -1;
  double goal_p = 0, goal_t = -1;
  int return_space = -1;  // cyclic space a one-shot space was entered from
  double return_p = 0;
  bool holding = false;   // a one-shot space's way on was refused: hold its last pose
};

// Transition bookkeeping of one request, for logs (motion times in seconds).
struct TransitionRecord {
  int from = -1, to = -1;
  double request_time = -1;  // the request took effect (tick)
  double switch_time = -1;   // the character switched to the target
  double arrive_time = -1;   // the requested state was reached
  double search_seconds = 0;  // wall-clock CPU of the search (not deterministic: logs only)
  TransitionPath path;
};

// Events of the last step().
struct StepEvents {
  int searches = 0;     // transition searches run
  int switches = 0;     // switches to a target space
  int arrivals = 0;     // paths completed
  int refused = 0;      // requests refused at their tick (no path found)
  double search_seconds = 0;  // wall-clock time of this step's searches
};

// One output frame (allocated once).
struct CharacterFrame {
  BlendedFrame positions;  // root frame, planes x | y | z
  BlendedFrame normals;    // root frame, planes x | y | z
  RootTransform root;      // world pose of the root
  float fade_weight = 1;   // weight of the current space (1 outside a cross-fade)
  // The key textures to blend and their weights (runtime/textures.h), with the geometry's input
  // weights and cross-fade; count 0 when the asset has no textures. blend_texture_image()
  // turns it into the frame's texture on the CPU.
  TextureBlend textures;
};

class Character {
 public:
  // `graph` must outlive the character. `transitions` are the search options (the asset's).
  // Throws InputError for an empty graph, ConfigError for bad options.
  Character(const MotionGraph& graph, const TransitionOptions& transitions,
            const CharacterOptions& options = {});

  // Starts over in `space` at parameter p (clamped) and time t, the root at `root`; forgets
  // requests, paths and the clock. Returns the clamping status.
  RequestStatus reset(int space, double p, double t = 0, const RootTransform& root = {});

  // The parameter the current motion (or the one a transition goes to) ramps to.
  RequestStatus set_parameters(double p);
  // Go to `space` at parameter p and (optionally, t >= 0) time t. Same space without t: a
  // parameter change. Replaces a request not yet applied.
  RequestStatus request_motion(int space, double p, double t = -1);
  RequestStatus request_motion(std::string_view space, double p, double t = -1);
  // Steering [rad/s], clamped to options.max_turn_rate; takes effect at the next tick.
  void set_turn_rate(double rad_per_second);

  // Called at every tick before it is integrated (e.g. a controller): may call the request
  // functions above, which then take effect at that very tick.
  struct TickHook {
    virtual ~TickHook() = default;
    virtual void on_tick(Character& character, const CharacterState& state) = 0;
  };
  void set_tick_hook(TickHook* hook) { hook_ = hook; }

  // Advances by dt seconds of motion time (dt >= 0) and evaluates the frame. No allocation.
  const CharacterFrame& step(double dt);
  // Plays a copy of a state forward by `seconds` as step() would, but without requests, plans,
  // the tick hook or any other side effect: a path under way plays to its end, then the motion
  // plays on freely. For predictions (where a transition path would take the root). No
  // allocation.
  void preview(CharacterState* state, double seconds) { advance(state, seconds, false); }

  // The frame of the last step (or of reset).
  const CharacterFrame& frame() const { return frame_; }
  // The state the last frame shows (between ticks: the committed tick advanced, not committed).
  const CharacterState& state() const { return shown_; }
  double time() const { return time_; }
  const StepEvents& events() const { return events_; }
  // The last transition requested (its times fill in as it plays).
  const TransitionRecord& last_transition() const { return record_; }
  // Requests or parameter changes clamped since reset.
  int clamp_count() const { return clamps_; }

  const MotionGraph& graph() const { return graph_; }
  const CharacterOptions& options() const { return options_; }
  const TransitionOptions& transition_options() const { return transitions_; }

 private:
  struct Request {
    bool pending = false;
    int space = -1;
    double p = 0, t = -1;
    std::int64_t due_tick = 0;
  };
  void advance(CharacterState* s, double seconds, bool commit);
  void prepare_tick();
  bool start_transition(int target, double p, double t);
  void plan_next();
  void evaluate(const CharacterState& s);
  // At a switch: the alignment and length of the cross-fade (see the top of this file).
  void plan_fade(CharacterState* s);
  // The 99th percentile of the vertex speed of `space` at parameter p [m/s].
  double motion_speed(int space, double p) const;
  double clamp_p(int space, double p, bool* clamped) const;
  std::int64_t due_tick_now() const;

  const MotionGraph& graph_;
  TransitionOptions transitions_;
  CharacterOptions options_;
  int num_spaces_ = 0;
  std::array<int, 64 * 64> next_hop_{};  // first space of the shortest route, -1: none
  TransitionSearch search_;
  TickHook* hook_ = nullptr;

  CharacterState state_;   // committed at tick_
  CharacterState shown_;   // what frame_ shows
  std::int64_t tick_ = 0;           // state_ is at time tick_ * tick_seconds
  std::int64_t prepared_tick_ = -1;  // the tick whose requests and hook have run
  std::int64_t hook_tick_ = -1;      // >= 0 while the hook runs: requests are due then
  double time_ = 0;                  // motion time of the last step
  Request request_, parameter_, turn_;
  StepEvents events_;
  TransitionRecord record_;
  int clamps_ = 0;
  CharacterFrame frame_;
  // Per space, the vertex speed p99 at kSpeedSamples parameters from min to max [m/s].
  static constexpr int kSpeedSamples = 5;
  std::array<std::array<float, kSpeedSamples>, 64> speeds_{};
  BlendedFrame scratch_a_, scratch_b_;  // plan_fade's evaluations, the fading blend
};

// World positions of the frame (root applied): #V points into `out` (resized once).
void character_world_positions(const CharacterFrame& frame, std::vector<Vec3f>* out);
void character_world_normals(const CharacterFrame& frame, std::vector<Vec3f>* out);

}  // namespace fourd
