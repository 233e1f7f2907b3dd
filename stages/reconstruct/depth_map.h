#pragma once
// Per-camera depth maps by a hull-guided plane sweep.
//
// The visual hull contains the performer, so along every pixel's ray the surface lies at or
// behind the hull's first hit. For each reference camera the sweep tries depths "hull depth +
// offset" for a range of offsets; every hypothesis is a surface parallel (along the rays) to
// the hull, so the matching windows follow the hull's slant rather than being fronto-parallel.
// Each hypothesis warps the neighbouring cameras' images onto the reference image (cv::remap)
// and scores every pixel by the normalised cross-correlation (NCC) of its window, computed with
// box filters over the silhouette only (background pixels are left out of the window, so the
// outline is matched as well as the inside). A pixel's score is the best (or the mean) of the
// scores of the neighbours that see the point: the best lets a point that one neighbour sees
// past an occluder the hull does not show still match. The best offset is refined to sub-step
// precision by a parabola through its neighbours' scores. The maps are then checked against
// each other (keep_consistent_depths), which removes the lone wrong matches the best score
// lets through.
#include <opencv2/core.hpp>
#include <string>
#include <vector>

#include "pipeline/core/config.h"
#include "stages/reconstruct/pinhole.h"

namespace fourd::reconstruct {

// The options are the members visit() lists, with their help; the others are tuned values,
// not options (docs/reconstruct.md, "Advanced"); internal_lengths() lists the tuned lengths
// scaled to the subject.
struct DepthMapOptions {
  int neighbours = 2;                  // cameras matched against each reference camera
  double max_angle_deg = 100;          // ... whose optical axes differ by at most this [deg]
  int window_radius = 2;
  double front_margin = 0.01;          // depth searched in front of the hull surface [m]
  double search_depth = 0.10;          // depth searched behind the hull surface [m]
  double step = 0.0025;                // depth step of the sweep [m]
  double min_ncc = 0.7;
  double min_texture = 1.5;            // window standard deviation below this [grey levels]: no depth
  double min_window_fill = 0.5;        // fraction of the window inside the silhouette
  double occlusion_margin = 0.10;      // a neighbour sees a point at most this far behind its hull [m]
  double prefilter_sigma = 0.0;
  // How the neighbours' NCC scores make a pixel's score: "mean" of the neighbours that see the
  // point, or the "best" one (a point one neighbour sees past an occluder still matches).
  std::string neighbour_score = "best";
  int consistent_views = 1;
  double consistency_tolerance = 0.01; // depths agreeing this closely along their rays [m]

  template <class V>
  void visit(V& v) {
    v("window_radius", window_radius, "NCC window radius [px]: the window is (2 r + 1)^2 pixels",
      Range{1, 15});
    v("min_ncc", min_ncc, "smallest accepted mean NCC (best mean NCC below this: no depth)",
      Range{-1, 1});
    v("prefilter_sigma", prefilter_sigma, "Gaussian blur of the grey images before matching [px]",
      Range{0, 5});
    v("consistent_views", consistent_views,
      "other cameras' depth maps that must agree with a depth (0: keep every depth)", Range{0, 64});
  }
  template <class V>
  void internal_lengths(V& v) {
    v("front_margin", front_margin, "", Length{0, 0.5});
    v("search_depth", search_depth, "", Length{1e-5, 2});
    v("step", step, "", Length{1e-6, 0.1});
    v("occlusion_margin", occlusion_margin, "", Length{0, 2});
    v("consistency_tolerance", consistency_tolerance, "", Length{1e-6, 0.5});
  }
  void check() const;
};

// One camera of one frame, as depth estimation needs it.
struct StereoView {
  PinholeCamera camera;
  cv::Mat gray;         // CV_32F grey levels 0..255, undistorted to `camera`
  // CV_32F first hit per pixel [m] (0 = outside) of the surface the sweep searches behind: the
  // visual hull, or in a guided pass the previous pass's fused surface.
  cv::Mat hull_depth;
  cv::Rect roi;         // bounding rectangle of the hull's pixels
};

struct DepthMap {
  cv::Mat depth;  // CV_32F, full image, depth along the optical axis [m], 0 = none
  cv::Mat score;  // CV_32F, mean NCC of the chosen depth (-1 where none)
  cv::Mat filled; // CV_8U, 1 where the depth was filled in from matched ones around it (or empty)
};

// The `count` cameras whose optical axes are closest in angle to `ref`'s, at most
// `max_angle_deg` apart, closest first.
std::vector<int> select_neighbours(const std::vector<PinholeCamera>& cameras, int ref, int count,
                                   double max_angle_deg);

// The depth map of views[ref] matched against views[neighbours]. Pixels outside the hull, with
// too little texture, seen by no neighbour or without a clear best depth inside the searched
// range get depth 0.
DepthMap estimate_depth_map(const std::vector<StereoView>& views, int ref,
                            const std::vector<int>& neighbours, const DepthMapOptions& options);

// Geometric consistency: a depth of one map is kept only when at least `min_views` other maps
// see the same point, i.e. its 3-D point projects into them onto a depth within `tolerance`.
// A depth no other map confirms is a lone match (a repeated texture, a window across an
// occluding edge). `min_views` 0 keeps every depth. Returns the number of depths removed.
std::size_t keep_consistent_depths(const std::vector<PinholeCamera>& cameras,
                                   std::vector<DepthMap>& maps, int min_views, double tolerance);

// Unit normals (world coordinates, facing the camera) of a depth map by central differences of
// its back-projected points; 0 where a neighbour has no depth or jumps by more than
// `max_jump` [m].
cv::Mat depth_map_normals(const PinholeCamera& camera, const cv::Mat& depth, double max_jump);

}  // namespace fourd::reconstruct
