#pragma once
// The `align` stage: non-sequential temporal alignment of every reconstructed frame of every
// take to one template mesh (Huang et al. 2011, as used by Casas et al. 2012).
//
//   1. A shape histogram per frame, the distance between every pair of frames, a minimum
//      spanning tree over them, rooted at its most central frame (or a chosen one).
//   2. The template: the root frame remeshed to a vertex budget.
//   3. Registration along the tree, parent to child (independent branches in parallel): each
//      child starts from its parent's deformation, moved by a rigid guess from the shape
//      histograms. Alignment errors do not accumulate along a take.
//   4. Frames that cannot be used (empty, non-manifold, unreadable) are excluded; a frame whose
//      registration fails (large residual or uncovered surface) is re-parented to the most
//      similar aligned frame; when that fails too, its best fit is kept and flagged (or, with
//      keep_failed_fits off, it is excluded); all of it in the report. A fit that passed with
//      an rms far above the median is registered again from other parents, the best kept.
//   5. Optionally the sequential baseline: the same registration frame to frame in time order.
//
// Reads <input>/<take>/<frame>.ply (reconstruct/, or oracle/reconstruct/ in oracle mode) and
// writes <output>/template.ply, <output>/<take>/<frame>.ply (template topology), tree.json,
// report.json, options.yaml, and with the baseline sequential/<take>/<frame>.ply.
#include <functional>
#include <string>
#include <vector>

#include "pipeline/core/config.h"
#include "pipeline/core/session.h"
#include "stages/align/registration.h"
#include "stages/align/shape_descriptor.h"
#include "stages/common/stage.h"

namespace fourd::align {

// The options are the members visit() lists, with their help; the others are tuned values,
// not options (docs/align.md, "Advanced").
struct AlignOptions {
  int template_vertices = 3000;   // the paper's 3,000
  int remesh_iterations = 10;     // isotropic remeshing passes for the template
  double handle_voxel = 0.005;
  int handle_radius = 1;          // largest closing / opening radius of the handle removal
                                  // [voxels], tried from 1 up: the larger, the thicker the
                                  // handles it removes
  std::string root;
  double root_tolerance = 0.02;   // of the frames whose summed shape distance to all frames is
                                  // within this fraction of the least, the one whose surface has
                                  // the fewest handles is the root (an arm merged into the body
                                  // makes a poorer template)
  double max_surface_rms = 0.02;
  double max_uncovered_fraction = 0.05;  // a fit leaving more of the frame uncovered failed
  double far_edge_factor = 4.0;   // tree edges longer than this x the median are flagged
  int reparent_attempts = 3;
  // Register frames the self-diagnosis finds wrong on their surface again (align.md, item 6).
  // Off: on the default sample it changed 3 of 95 verdicts and no metric, and on the tiny
  // sample it left walk_fast a cycle that does not close. Not a user option until it helps.
  bool retry_diagnosed = false;
  // A fit whose patch jumps from its take neighbours by more than this x the self-diagnosis's
  // jump limit (a limb fitted to the other one) is registered again (align.md, item 6); 0:
  // never. 6: second_body's swapped legs are 13x, a fast hand at 12 fps 4-5x.
  double retry_jump_factor = 6;
  double outlier_rms_factor = 2;
  bool exclude_non_manifold = true;  // non-manifold frames are excluded (else flagged only)
  bool keep_failed_fits = true;
  double max_volume_ratio = 1.35;
  bool sequential_baseline = false;
  DescriptorOptions descriptor;
  RegistrationOptions registration;

  template <class V>
  void visit(V& v) {
    v("template_vertices", template_vertices, "template vertex count (and so the asset's)",
      Range{100, 1000000});
    v("handle_voxel", handle_voxel,
      "voxel of the morphological clean-up that removes the root frame's small handles (tunnels, "
      "an arm merged with the body) before it becomes the template [m]; 0: none",
      Length{0, 1});
    v("root", root,
      "root frame as <take>/<frame>; empty: the most central frame (least summed shape distance "
      "to all frames), the template's");
    v("max_surface_rms", max_surface_rms,
      "a fit with a larger vertex-to-surface rms failed [m]", Length{1e-06, 100});
    v("reparent_attempts", reparent_attempts,
      "other parents tried for a frame whose registration failed", Range{0, 100});
    v("outlier_rms_factor", outlier_rms_factor,
      "a fit that passed with more than this x the median rms of the aligned frames is "
      "registered again from its neighbours in time and up to reparent_attempts other similar "
      "frames, the least stretched of its closest fits kept; 0: never",
      Range{0, 1000});
    v("keep_failed_fits", keep_failed_fits,
      "a frame whose every fit failed keeps its best, flagged (else it is excluded and the take "
      "has a gap)");
    v("max_volume_ratio", max_volume_ratio,
      "largest ratio of two takes' median volumes of one character (above: refused as different "
      "characters)",
      Range{1, 100});
    v("sequential_baseline", sequential_baseline,
      "also run the frame-to-frame baseline (sequential/)");
    v("registration", registration, "pairwise non-rigid registration");
  }
  template <class V>
  void internal_lengths(V& v) {
    v("descriptor", descriptor, "");
  }
};

// What happened to one frame.
struct FrameStatus {
  std::string take;
  int frame = 0;
  bool aligned = false;
  // Any of: unreadable, empty, non_manifold, far_from_parent, registration_failed,
  // reparented, orphaned (its parent failed), refitted / outlier_fit (its fit's rms was far
  // above the median: registered again from other parents, better / not).
  std::vector<std::string> flags;
  std::string error;          // why it was excluded (empty when aligned)
  int handles = -1;           // the mesh's genus (ManifoldReport::handles; -1: unknown)
  int parent = -1;            // index of the frame it was registered from; -1 for the root
  double parent_distance = 0; // shape distance to it
  int depth = 0;              // registrations between the root and this frame
  FitStats fit;
  double seconds = 0;  // registration wall time
};

// Runs the stage (or the job `args` names). `adjust`, when given, changes the options after
// they are read and scaled to the subject, before any job uses them: how a test sets tuned
// values that session.yaml cannot.
void run_align(const Session& session, const StageArgs& args,
               const std::function<void(AlignOptions&)>& adjust = {});

}  // namespace fourd::align
