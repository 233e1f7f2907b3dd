#pragma once
// The takes the synth tests perform: one MotionSpec builder per kind of motion.
#include <string>

#include "stages/synth/motion.h"

namespace fourd::synth::test {

inline MotionSpec make_spec(const std::string& kind, int frames) {
  MotionSpec spec;
  spec.take = kind;
  spec.kind = kind;
  spec.frames = frames;
  return spec;
}

inline MotionSpec walk(double speed, int frames = 80) {
  MotionSpec s = make_spec("walk", frames);
  s.speed = speed;
  return s;
}

inline MotionSpec run(double speed, int frames = 60) {
  MotionSpec s = make_spec("run", frames);
  s.speed = speed;
  return s;
}

inline MotionSpec turn(double speed, double rate, int frames = 100) {
  MotionSpec s = make_spec("turn", frames);
  s.speed = speed;
  s.turn_rate = rate;
  return s;
}

inline MotionSpec jump(double length, double height, int frames = 70) {
  MotionSpec s = make_spec("jump", frames);
  s.jump_length = length;
  s.jump_height = height;
  return s;
}

inline MotionSpec reach(double x, double y, double z, int frames = 60) {
  MotionSpec s = make_spec("reach", frames);
  s.reach_target = {x, y, z};
  return s;
}

inline MotionSpec dance(double turn_rate, int frames = 50) {
  MotionSpec s = make_spec("dance", frames);
  s.turn_rate = turn_rate;
  return s;
}

}  // namespace fourd::synth::test
