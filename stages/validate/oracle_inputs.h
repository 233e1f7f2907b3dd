#pragma once
// Oracle inputs (docs/design.md "Oracle inputs"): stage inputs made from the ground truth of a
// synthetic session, so each stage's own error can be measured apart from the errors it
// inherits. `fourd-validate SESSION --prepare-oracle` writes, replacing the folder as a whole:
//
//   oracle/segment/<take>/<camera>/<frame>.png  ground-truth silhouettes (segment/'s layout)
//   oracle/reconstruct/<take>/<frame>.ply       ground-truth surfaces re-meshed with fresh
//                                               random connectivity per frame (+ optional
//                                               noise), so alignment cannot use the topology
//   oracle/align/template.ply, <take>/<frame>.ply   ground truth in its one consistent topology
//   oracle/options.yaml                         the options used
//
// Only the validate stage reads ground_truth/.
#include <Eigen/Core>

#include "pipeline/core/config.h"
#include "pipeline/core/mesh.h"
#include "pipeline/core/session.h"

namespace fourd::validate {

// The options are the members visit() lists, with their help; the others are tuned values,
// not options (docs/validate.md, "Advanced").
struct OracleOptions {
  double remesh_voxel = 0.008;  // grid spacing of the fresh re-meshing [m]
  double noise_sigma = 0.0;
  int seed = 1;                 // random grid offsets and noise
  template <class V>
  void visit(V& v) {
    v("noise_sigma", noise_sigma, "Gaussian noise along the normals of re-meshed surfaces [m]",
      Range{0, 0.1});
  }
};

// Writes <session>/oracle/ from ground_truth/ (see above), atomically as a whole folder.
// Options come from session.yaml's stages.oracle section. Throws InputError when the session
// has no ground truth.
void prepare_oracle_inputs(const Session& session, const OracleOptions& options);

}  // namespace fourd::validate
