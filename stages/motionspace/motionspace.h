#pragma once
// The motionspace stage: turns each registered motion class (timewarp/<class>.twarp) into a
// parametric motion space the runtime evaluates at (t, p) (runtime/motion_space.h):
//  - the inputs' root-free shapes, plus hybrid references chosen by recursive bisection until
//    the hybrid blend is within epsilon of the non-linear blend (hybrid_build.h);
//  - root curves and per-input timing from the timewarp stage;
//  - the parameter map w = h^-1(p), sampled on the hybrid blend (parameters.h), and its
//    accuracy: the parameter measured on the blended motion against the requested one.
// Also the paper's Table 1 and Figure 4 on the pair of takes whose shapes differ most in
// rotation (table1.h).
//
// Reads timewarp/ (timewarp_oracle/ in oracle mode); writes motionspace/ (motionspace_oracle/):
//   <class>.mspace   the motion space (runtime/motion_space.h file format)
//   <class>.json     references, errors, parameter range and accuracy
//   table1.json      Table 1 numbers; figure4.png the blend at five weights with error maps
//   summary.json     what validation reads first; options.yaml the options used
// Every class is computed before the folder is replaced as a whole.
#include "pipeline/core/config.h"
#include "pipeline/core/session.h"
#include "pipeline/exchange/warped_class.h"
#include "runtime/motion_space.h"
#include "stages/common/stage.h"
#include "stages/motionspace/hybrid_build.h"
#include "stages/motionspace/parameters.h"

namespace fourd::motionspace {

// The options are the members visit() lists, with their help; the others are tuned values,
// not options (docs/motionspace.md, "Advanced").
struct MotionspaceOptions {
  double epsilon = 0.005;
  int max_depth = 8;          // bisection levels per cell at most
  int max_references = 32;
  int parameter_samples = 16; // parameter samples per pair of consecutive inputs
  int parameter_checks = 21;  // requests checked for the parameter accuracy
  bool table1 = true;
  int table1_weights = 19;    // test weights of Table 1, evenly inside (0, 1)
  template <class V>
  void visit(V& v) {
    v("epsilon", epsilon, "hybrid blend within this of the non-linear blend [m]",
      Length{1e-7, 1});
    v("max_references", max_references, "hybrid references added per class at most",
      Range{0, 100000});
    v("table1", table1, "compute the paper's Table 1 and Figure 4");
  }
  // Throws ConfigError naming the field (epsilon must be > 0).
  void check() const;
  HybridBuildOptions hybrid() const { return {epsilon, max_depth, max_references}; }
};

struct MotionSpaceReport {
  HybridBuildReport hybrid;
  ParameterMapReport parameters;
  ParameterAccuracy accuracy;
};

// One class's motion space. Throws ConfigError for bad options or an unknown parameter,
// InputError for takes that do not fit (naming the class and takes).
MotionSpace build_motion_space(const WarpedClass& warped,
                               const MotionspaceOptions& options, MotionSpaceReport* report);

void run_motionspace(const Session& session, const StageArgs& args);

}  // namespace fourd::motionspace
