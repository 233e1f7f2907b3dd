#pragma once
// The procedural motion generators behind generate_motion(). Internal to the synth stage.
#include "stages/synth/motion.h"
#include "stages/synth/motion_rig.h"

namespace fourd::synth::detail {

// walk, run and turn: a periodic gait along a straight line or a circular arc.
MotionClip generate_gait(const Rig& rig, const MotionSpec& spec, double fps);
// jump: stand, crouch, take off, ballistic flight, land, recover.
MotionClip generate_jump(const Rig& rig, const MotionSpec& spec, double fps);
// reach: stand, move the right palm to the target and back.
MotionClip generate_reach(const Rig& rig, const MotionSpec& spec, double fps);

// The root's state at frame 0 of a take.
RootState start_state(const MotionSpec& spec);

}  // namespace fourd::synth::detail
