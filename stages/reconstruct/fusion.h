#pragma once
// Fusion of per-camera depth maps with the visual hull into one signed field (negative
// inside), whose zero level set is the reconstructed surface.
//
// Near the hull surface, every depth map votes a truncated signed distance along its rays
// (TSDF: positive in front of the measured surface, up to `truncation`; points further than
// `truncation` behind it are not voted on, they may be hidden). The hull adds a weak vote of its
// own, so the surface falls back to the hull where no camera measured a depth, and the result
// is trimmed to the hull (max with the hull field): nothing can come out of it.
#include <vector>

#include "pipeline/core/config.h"
#include "pipeline/core/isosurface.h"
#include "stages/reconstruct/depth_map.h"
#include "stages/reconstruct/pinhole.h"

namespace fourd::reconstruct {

// The options are the members visit() lists, with their help; the others are tuned values,
// not options (docs/reconstruct.md, "Advanced"); internal_lengths() lists the tuned lengths
// scaled to the subject.
struct FusionOptions {
  double truncation = 0.015;   // TSDF truncation [m]
  double band = 0.12;          // depth inside the hull where depth maps are fused [m]
  // Below 1, so that one or two cameras that see into a concavity (between the legs, under the
  // arms) can carve the hull there; the depths have passed the consistency check, so a lone
  // wrong match does not.
  double hull_weight = 0.3;
  double score_weight = 1.0;   // 1: weight votes by their NCC score above min_ncc; 0: equally
  // Weight of a depth filled in from the matched ones around a hole (depth_fill.h), relative
  // to one matched depth's. Small: a filled depth too far behind the surface carves it away
  // (on the default sample: 0.05 gives the best completeness and F-score, 0.1 the best p90
  // accuracy, 0.3 loses completeness).
  double filled_weight = 0.05;
  template <class V>
  void visit(V& v) {
    v("hull_weight", hull_weight, "weight of the hull's vote relative to one depth map's",
      Range{0, 1000});
  }
  template <class V>
  void internal_lengths(V& v) {
    v("truncation", truncation, "", Length{1e-5, 0.5});
    v("band", band, "", Length{0, 2});
  }
};

// `field` holds the visual hull (VisualHull::grid()) on input and the fused field on output.
// With `depth_weight`, that grid (resized to the field's) receives every sample's summed weight
// of depth votes: 0 where the surface can only be the hull's (no camera measured a depth
// there, as in a concavity every view is blocked from).
void fuse_depth_maps(ScalarGrid& field, const std::vector<PinholeCamera>& cameras,
                     const std::vector<DepthMap>& depth_maps, double min_score,
                     const FusionOptions& options, ScalarGrid* depth_weight = nullptr);

// Confidence of every vertex of a surface fused with `depth_weight` (fuse_depth_maps): W / (W +
// hull_weight), W the largest depth weight of the grid samples around the vertex - the share of
// the depths' votes in where the surface is, 0 where the hull alone put it.
std::vector<float> surface_confidence(const Mesh& mesh, const ScalarGrid& depth_weight,
                                      const FusionOptions& options);

}  // namespace fourd::reconstruct
