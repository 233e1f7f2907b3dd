#include "runtime/transition_jump.h"

#include <algorithm>
#include <cmath>

#include "pipeline/core/se2.h"

namespace fourd {

double motion_displacement_p99(const MotionGraph& graph, int space_index, double p,
                               double frame_seconds) {
  const GraphSpace& space = graph.spaces[space_index];
  const MotionSpace& motion = space.motion;
  std::array<float, 3> w{};
  space_weights(space, p, &w);
  const std::span<const float> ws(w.data(), static_cast<std::size_t>(space.num_inputs()));
  const double duration = blended_duration(motion, ws);
  const int frames = std::max(2, static_cast<int>(std::ceil(duration / frame_seconds)) + 1);
  BlendedFrame frame = make_blended_frame(motion.blend);
  BlendSources sources;
  const int nv = motion.blend.num_vertices;
  std::vector<Vec3f> previous(nv), current(nv);
  std::vector<float> steps;
  steps.reserve(static_cast<std::size_t>(frames) * nv);
  double t = 0;
  for (int f = 0; f < frames; ++f) {
    hybrid_blend_sources(motion.blend, std::min(t, 1.0), ws, &sources);
    weighted_sum(sources, motion.blend.frame_stride(), frame.data.data());
    const RootPose r = space_root(motion, std::min(t, 1.0), ws);
    const float c = std::cos(r.heading), s = std::sin(r.heading);
    for (int v = 0; v < nv; ++v) {
      const float x = frame.x()[v], y = frame.y()[v];
      current[v] = Vec3f(r.x + c * x - s * y, r.y + s * x + c * y, frame.z()[v]);
      if (f > 0) steps.push_back((current[v] - previous[v]).norm());
    }
    std::swap(previous, current);
    if (t >= 1) break;
    // Advance one frame at the blended pace where the frame starts.
    const double pace = blended_seconds_per_t(motion, std::min(t, 1.0), ws);
    t += pace > 0 ? frame_seconds / pace : 1.0;
  }
  if (steps.empty()) return 0;
  const auto k = static_cast<std::ptrdiff_t>(std::floor(0.99 * static_cast<double>(steps.size() - 1)));
  std::nth_element(steps.begin(), steps.begin() + k, steps.end());
  return steps[static_cast<std::size_t>(k)];
}

double VertexJumpMeter::add(const CharacterFrame& frame) {
  character_world_positions(frame, &current_);
  double worst = 0;
  if (previous_.size() == current_.size()) {
    for (std::size_t v = 0; v < current_.size(); ++v) {
      worst = std::max(worst, static_cast<double>((current_[v] - previous_[v]).squaredNorm()));
    }
  }
  std::swap(previous_, current_);
  return std::sqrt(worst);
}

bool CrossFadeWindow::counts(const TransitionRecord& r, const CharacterState& s) {
  const bool switched = r.switch_time >= 0;
  const bool first = switched && r.switch_time != counted_switch_;
  const bool in = first || (switched && (s.fading || was_fading_));
  if (first) counted_switch_ = r.switch_time;
  was_fading_ = s.fading;
  return in;
}

TransitionJump measure_transition_jump(Character& character, const MotionState& from,
                                       const TransitionTarget& to, double frame_seconds,
                                       double max_seconds) {
  TransitionJump out;
  const MotionGraph& graph = character.graph();
  character.reset(from.space, from.p, from.t);
  VertexJumpMeter meter;
  CrossFadeWindow window;
  meter.add(character.frame());
  character.request_motion(to.space, to.p, to.t);
  bool arrived = false;
  for (double time = 0; time < max_seconds; time += frame_seconds) {
    const CharacterFrame& frame = character.step(frame_seconds);
    const double step = meter.add(frame);
    const TransitionRecord& r = character.last_transition();
    if (window.counts(r, character.state())) out.worst_m = std::max(out.worst_m, step);
    arrived = arrived || r.arrive_time >= 0;
    if (arrived && !character.state().fading) break;
  }
  out.played = arrived && !character.state().fading;
  out.source_p99_m = motion_displacement_p99(graph, from.space, from.p, frame_seconds);
  out.target_p99_m = motion_displacement_p99(graph, to.space, to.p, frame_seconds);
  return out;
}

}  // namespace fourd
