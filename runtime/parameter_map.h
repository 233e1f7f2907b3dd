#pragma once
// High-level parameter control of a motion space (paper section 3.1, after Kovar & Gleicher
// 2004): the user asks for a parameter p ("speed 1.8 m/s", "jump length 1.2 m") and the runtime
// finds the blend weights w = h^-1(p).
//
// The offline stage samples h along a path through the weight simplex that visits the inputs
// in parameter order (session.yaml lists each class's takes that way): path position s in
// [0, N - 1] blends input floor(s) with input floor(s) + 1, so s = 0, 1, 2 are the inputs
// themselves. It measures p on the blended motion at K path positions; the samples are strictly
// monotone in s (increasing or decreasing), so the inverse is a binary search and a linear
// interpolation. A parameter outside the captured range is clamped to it, and the lookup says
// so. Nothing here allocates.
#include <span>
#include <string>
#include <vector>

namespace fourd {

struct ParameterMap {
  std::string parameter;       // "speed", "direction", "length", "height", "reach"
  std::string unit;            // "m/s", "deg/s", "m"
  int num_inputs = 0;          // N, 1..3
  std::vector<double> path;    // K >= 1 path positions, increasing from 0 to N - 1
  std::vector<double> values;  // K parameter values h(path[k]), strictly monotone

  double min_value() const;
  double max_value() const;
  // Throws InputError if sizes disagree, the path does not run from 0 to N - 1 in increasing
  // order, or the values are not finite and strictly monotone (constant for N = 1).
  void check() const;
};

// The weights at path position s (clamped to [0, N - 1]) into w[0 .. N).
void path_weights(int num_inputs, double s, std::span<float> w);

struct ParameterLookup {
  double requested = 0;      // what was asked for
  double applied = 0;        // what the weights produce: the request clamped to the range
  double path_position = 0;  // s
  bool clamped = false;      // the request was outside [min_value, max_value]
};

// w = h^-1(p): the weights (N entries written into w) whose blend has parameter p, or the
// nearest end of the captured range. A non-finite p counts as out of range (lowest value).
ParameterLookup weights_for_parameter(const ParameterMap& map, double p, std::span<float> w);

// h at path position s, interpolated between the samples.
double parameter_at_path(const ParameterMap& map, double s);

}  // namespace fourd
