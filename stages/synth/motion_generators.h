#pragma once
// The procedural motion generators behind generate_motion(). Internal to the synth stage.
#include <functional>

#include "stages/synth/motion.h"
#include "stages/synth/motion_rig.h"

namespace fourd::synth::detail {

// walk, run and turn: a periodic gait along a straight line or a circular arc.
MotionClip generate_gait(const Rig& rig, const MotionSpec& spec, double fps);
// jump: stand, crouch, take off, ballistic flight, land, recover.
MotionClip generate_jump(const Rig& rig, const MotionSpec& spec, double fps);
// reach: stand, move the right palm to the target and back.
MotionClip generate_reach(const Rig& rig, const MotionSpec& spec, double fps);
// dance: steps on the spot with wide arm swings, a spin, and back to standing.
MotionClip generate_dance(const Rig& rig, const MotionSpec& spec, double fps);

// walk, trot and gallop of the quadruped (character.body quadruped; quadruped_gait.cpp).
MotionClip generate_quadruped_gait(const Skeleton& skeleton, const MotionSpec& spec, double fps);

// The root's state at frame 0 of a take.
RootState start_state(const MotionSpec& spec);
// The frames of a one-shot take (spec.frames at `fps`): the root and the pose at each frame's
// time [s], the phase the frame's index over the frame count.
MotionClip sample_one_shot(const Rig& rig, const MotionSpec& spec, double fps,
                           const std::function<RootState(double)>& root,
                           const std::function<WorldPose(double)>& pose);
// The frames of a cyclic take (spec.frames at `fps`): the root and the pose at each frame's
// time [s], the phase its gait phase's fraction; cycle_frames as given.
MotionClip sample_cyclic(const Skeleton& skeleton, const MotionSpec& spec, double fps, double cycle_frames,
                         const std::function<RootState(double)>& root, const std::function<double(double)>& phase,
                         const std::function<WorldPose(double)>& pose);
// Throws ConfigError when the take has fewer frames than `seconds` of motion need at `fps`.
void require_frames(const MotionSpec& spec, double seconds, double fps);

}  // namespace fourd::synth::detail
