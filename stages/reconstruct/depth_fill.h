#pragma once
// Filling the holes that matching leaves inside a depth map.
//
// Plane-sweep stereo finds no depth where the image has no texture (a flat-coloured patch of
// the costume), where no neighbour scores above min_ncc, or where the consistency check finds
// no other camera that confirms it. Without a depth, fusion falls back to the visual hull
// there, which can stand several centimetres in front of a flat chest or back (the wedge the
// two cameras on either side of it carve). A hole mostly surrounded by matched depths is a
// patch of that surface: its depth behind the hull is filled in by harmonic (Laplace)
// interpolation between the matched depths' on its border and 0 where it borders the
// silhouette's outline (there the hull touches the surface it was carved around); the border's
// matched depths are taken as their local median, so a lone wrong match does not spread. Holes
// that are large or border the outline for much of their length (a grazing rim) are left
// empty. Filled depths are marked (DepthMap::filled) and vote with little weight in fusion: a
// filled depth too far behind the surface would carve it away.
#include <cstddef>
#include <opencv2/core.hpp>

#include "pipeline/core/config.h"
#include "stages/reconstruct/depth_map.h"

namespace fourd::reconstruct {

// The options are the members visit() lists, with their help; the others are tuned values,
// not options (docs/reconstruct.md, "Advanced").
struct DepthFillOptions {
  bool enabled = true;
  int max_pixels = 20000;        // largest hole filled [px]
  double min_enclosed = 0.6;     // fraction of the hole's border that must have matched depths
  template <class V>
  void visit(V& v) {
    v("enabled", enabled, "fill holes of the depth maps from the matched depths around them");
  }
};

// Fills the holes of `map` inside the hull (hull_depth > 0, depth 0) that pass the checks above,
// within [hull_depth - front_margin, hull_depth + search_depth] (the sweep's range), and marks
// them in map.filled. Returns the number of pixels filled.
std::size_t fill_depth_holes(const cv::Mat& hull_depth, DepthMap& map, double front_margin,
                             double search_depth, const DepthFillOptions& options);

}  // namespace fourd::reconstruct
