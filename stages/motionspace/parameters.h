#pragma once
// High-level motion parameters measured on a (blended) motion, and the sampled map w = h^-1(p)
// built from them (paper section 3.1; runtime/parameter_map.h evaluates it).
//
// What each parameter measures, on the motion over t in [0, 1] (root curve, timing and body
// shapes as the runtime produces them):
//   speed      [m/s]   ground-plane root displacement over the cycle / cycle duration
//   direction  [deg/s] heading change over the cycle / cycle duration (turn rate, + = left)
//   length     [m]     ground-plane root displacement from start to end (jump length)
//   height     [m]     highest rise of the torso centroid above its height at t = 0 (jump height)
//   reach      [m]     height of the hand when it is furthest from where it started, the
//                      "hand" being the vertex that moves furthest in the class's inputs
#include <Eigen/Core>
#include <span>
#include <string>
#include <vector>

#include "runtime/motion_space.h"

namespace fourd {

// What measuring one class's parameter needs, fixed per class.
struct ParameterProbe {
  std::string parameter;
  std::string unit;
  std::vector<double> torso;  // #V weights summing to 1 (height)
  int hand_vertex = -1;       // (reach)
};

// Throws ConfigError naming the class for an unknown parameter name. `template_positions`
// (3 x #V) picks the torso; the space's inputs pick the hand.
ParameterProbe make_parameter_probe(const std::string& motion_class, const std::string& parameter,
                                    const Eigen::Matrix3Xd& template_positions,
                                    const MotionSpace& space);

// The parameter of the space's blend at weights w, measured over every sample (the hybrid
// blend as the runtime evaluates it). `scratch` comes from make_motion_sample(space).
double measure_parameter(const ParameterProbe& probe, const MotionSpace& space,
                         std::span<const float> w, MotionSample* scratch);

struct ParameterMapReport {
  std::vector<double> input_values;  // the parameter of each input
  int dropped_samples = 0;           // samples left out to keep h strictly monotone
};

// Samples h along the path through the inputs in order (samples_per_segment per pair of
// consecutive inputs) and keeps a strictly monotone subset. Throws InputError naming the class
// and takes when the inputs are not in parameter order (h not monotone from input to input)
// or two inputs have the same parameter value.
ParameterMap build_parameter_map(const ParameterProbe& probe, const MotionSpace& space,
                                 int samples_per_segment, ParameterMapReport* report);

// Parameter accuracy: for `count` requests evenly inside the captured range, w = h^-1(p),
// then p measured again on the blended motion.
struct ParameterAccuracy {
  std::vector<double> requested;
  std::vector<double> measured;
  double max_error_pct = 0;   // of the parameter's range
  double mean_error_pct = 0;
};
ParameterAccuracy check_parameter_accuracy(const ParameterProbe& probe, const MotionSpace& space,
                                           int count);

}  // namespace fourd
