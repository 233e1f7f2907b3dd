#pragma once
// The reconstruction stage: one closed mesh per frame from the calibrated silhouettes and
// images, as a studio's reconstruction step does (Starck & Hilton 2007: visual hull refined by
// stereo):
//
//   1. visual hull of the silhouettes, as a signed field on a voxel grid (visual_hull.h);
//   2. per-camera depth maps by a hull-guided plane sweep against neighbouring cameras
//      (depth_map.h);
//   3. (method stereo) the depth maps' holes inside the hull filled from the depths around them
//      (depth_fill.h), then a second sweep over a narrow range guided by their fused surface
//      (its windows follow that surface's slant, not the hull's; GuidedPassOptions);
//   4. fusion of the depth maps with the hull into one field, trimmed to the hull (fusion.h),
//      or COLMAP's stereo_fusion + poisson_mesher from the first sweep's depth maps
//      (colmap_mvs.h);
//   5. isosurface, largest component, holes filled, remeshed to a vertex count
//      (mesh_cleanup.h).
//
// Outputs (in reconstruct/, or reconstruct_oracle/ in oracle mode):
//   <take>/<frame>.ply               the mesh (binary PLY)
//   <take>/<frame>.json              what happened to that frame: vertices, seconds per step,
//                                    warnings, or why it was skipped
//   visual_hull/<take>/<frame>.ply   the visual hull alone (isosurface of a coarser sampling
//                                    of the hull field, not remeshed; validation compares both)
//   report.json                      every frame's record plus a summary (warnings counted,
//                                    the subject's size and scale factor), rebuilt after each run
//   options.yaml                     the options used, the lengths derived from the subject's
//                                    size included
//   subject.json                     the subject's size, the scale factor and the volume the
//                                    cameras share (subject.h), for later stages
//
// Subject-relative lengths (config.h, Length) that session.yaml and its presets leave unset are
// scaled to the subject (subject.h), and the capture volume defaults to the volume the cameras
// share; every frame's result is checked against its silhouettes (plausibility.h).
//   calibration_check/               COLMAP's view of the calibration (calibration_check.h)
#include <filesystem>
#include <map>
#include <opencv2/core.hpp>
#include <string>
#include <vector>

#include "pipeline/core/camera.h"
#include "pipeline/core/config.h"
#include "pipeline/core/mesh.h"
#include "pipeline/core/session.h"
#include "stages/common/stage.h"
#include "stages/reconstruct/calibration_check.h"
#include "stages/reconstruct/colmap_mvs.h"
#include "stages/reconstruct/depth_fill.h"
#include "stages/reconstruct/depth_map.h"
#include "stages/reconstruct/fusion.h"
#include "stages/reconstruct/mesh_cleanup.h"
#include "stages/reconstruct/pinhole.h"
#include "stages/reconstruct/plausibility.h"
#include "stages/reconstruct/subject.h"
#include "stages/reconstruct/visual_hull.h"

namespace fourd::reconstruct {

// Sweeps guided by the previous pass's fused surface (method stereo). The option is `passes`;
// the others are tuned values (docs/reconstruct.md, "Advanced"), their lengths scaled to the
// subject (internal_lengths).
struct GuidedPassOptions {
  // Each pass's surface guides the next closer to the true one: on validation's 60 frames of the
  // default sample (three relaxation steps), completeness 0.9481 with one pass, 0.9495 with two,
  // 0.9500 with three, each pass ~0.3 s per frame.
  int passes = 2;
  double filled_weight = 1.0;     // weight of filled-in depths in the guide surface's fusion
  double front_margin = 0.015;    // depth searched in front of the guide surface [m]
  double search_depth = 0.03;     // depth searched behind the guide surface [m]
  double occlusion_margin = 0.03; // a neighbour sees a point at most this far behind its guide [m]

  template <class V>
  void visit(V& v) {
    v("passes", passes, "sweeps after the hull-guided one, each guided by the previous pass's "
      "surface (0: none)", Range{0, 10});
  }
  template <class V>
  void internal_lengths(V& v) {
    v("front_margin", front_margin, "", Length{0, 0.5});
    v("search_depth", search_depth, "", Length{1e-5, 2});
    v("occlusion_margin", occlusion_margin, "", Length{0, 2});
  }
};

// How a frame's surface is made: the option `method` (ReconstructOptions::visit has the help).
enum class Method { kStereo, kColmap, kVisualHull };

// The method a `method` option names; throws ConfigError for another name.
Method method_of(const std::string& name);

// Reconstruct's options: the members visit() lists (their help is there), and theirs; the
// others are tuned values, not options (docs/reconstruct.md, "Advanced").
struct ReconstructOptions {
  std::string method = "stereo";
  int min_cameras = 3;
  bool write_visual_hull = true;
  int frames_in_parallel = 0;
  // The pixel-sized values (NCC windows, blur, hole sizes) are tuned at 640x480, where the
  // subject spans ~300 px; a 1920x1080 camera reduced to 943x530 keeps sixteen cameras' frame
  // within the time budget (docs/reconstruct.md, "Studio size").
  int max_image_pixels = 500000;
  // A fine grid's isosurface (several 100k vertices) costs seconds to decimate. On the default
  // sample (6 mm voxels) the 12 mm isosurface decimated to 5,000 vertices covers more of the
  // true surface than the 18 mm one (completeness 0.941 -> 0.947): the decimation keeps its
  // creases.
  int isosurface_step = 2;
  // The visual hull written for validation is the isosurface of every n-th hull sample, not
  // decimated (cheap; at 4 x 6 mm it is within ~1-2 mm of the full-resolution hull).
  int visual_hull_step = 4;
  // The remeshed vertices put on the fused field's zero level at full resolution (trilinear
  // interpolation, Newton steps), which the coarser isosurface above only approximates
  // (methods stereo and visual_hull): on the default sample, completeness 0.9468 -> 0.9481 and
  // p90 accuracy 8.5 -> 8.3 mm, for 8 ms per frame.
  bool project_to_field = true;
  VisualHullOptions visual_hull;
  DepthMapOptions depth;
  DepthFillOptions depth_fill;
  GuidedPassOptions guided;
  FusionOptions fusion;
  ColmapMvsOptions colmap;
  RemeshOptions remesh;
  CalibrationCheckOptions calibration_check;
  SubjectScaleOptions scale;
  PlausibilityOptions checks;

  template <class V>
  void visit(V& v) {
    v("method", method,
      "stereo (the hull refined by multi-view stereo, fused here as a TSDF) | colmap (the same "
      "depth maps fused by COLMAP's stereo_fusion, meshed by poisson_mesher) | visual_hull (the "
      "hull alone)");
    v("min_cameras", min_cameras, "usable cameras a frame needs", Range{2, 1000});
    v("write_visual_hull", write_visual_hull, "also write visual_hull/<take>/<frame>.ply");
    v("frames_in_parallel", frames_in_parallel,
      "frames reconstructed at once (0: as many as threads)", Range{0, 1024});
    v("max_image_pixels", max_image_pixels,
      "images (and their silhouettes) with more pixels are reduced to about this many for the "
      "reconstruction (0: never)",
      Range{0, 1e9});
    v("isosurface_step", isosurface_step,
      "isosurfaces from every n-th field sample (1: the full grid)", Range{1, 8});
    v("visual_hull", visual_hull, "visual hull");
    v("depth", depth, "depth maps (hull-guided plane sweep)");
    v("depth_fill", depth_fill, "holes of the depth maps filled before fusion (method stereo)");
    v("guided", guided, "sweeps guided by the previous pass's surface (method stereo)");
    v("fusion", fusion, "depth map fusion (method stereo)");
    v("colmap", colmap, "COLMAP fusion and meshing (method colmap)");
    v("remesh", remesh, "final remeshing");
    v("calibration_check", calibration_check, "calibration check with COLMAP");
    v("scale", scale, "the subject's size, to which unset lengths are scaled");
    v("checks", checks, "every frame's result checked against its silhouettes (warnings)");
  }
  void check() const;
};

// The calibrated cameras and what every frame reuses of them.
struct Rig {
  std::vector<Camera> cameras;
  std::vector<PinholeCamera> pinholes;    // the same cameras without lens distortion
  std::vector<Undistorter> undistorters;  // images -> pinhole pixel grid
  static Rig from(std::vector<Camera> calibration);
};

// One frame's inputs: the usable cameras (indices into the rig; the caller leaves out, with a
// warning, cameras without an image or a sensible silhouette) and their images.
struct FrameInput {
  std::vector<int> cameras;
  std::vector<cv::Mat> images;       // 8-bit BGR as captured
  std::vector<cv::Mat> silhouettes;  // CV_8UC1, nonzero = performer
};

struct FrameResult {
  bool reconstructed = false;
  std::string failure;                 // why not, when !reconstructed
  Mesh mesh;
  Mesh visual_hull;                    // empty unless asked for
  std::vector<std::string> warnings;
  std::vector<std::pair<std::string, double>> seconds;  // per step, in order
  double depth_coverage = 0;           // fraction of hull pixels that got a depth
  // Fraction of the mesh's vertices of confidence below 0.5 (mostly the hull's: Mesh::confidence).
  double low_confidence_fraction = 0;
  PlausibilityReport plausibility;     // its warnings are also in `warnings`
};

// Reconstructs one frame. A frame that cannot be reconstructed (empty hull, COLMAP failing)
// comes back with reconstructed = false and the reason in `failure`. `work_dir` is used by
// method "colmap" only (its workspace).
FrameResult reconstruct_frame(const Rig& rig, const FrameInput& input,
                              const ReconstructOptions& options, bool want_visual_hull,
                              const std::filesystem::path& work_dir = {});

// The stage: every selected frame of every take, frames in parallel.
void run_reconstruct(const Session& session, const StageArgs& args,
                     const CalibrationCheckRequest& check_request);

}  // namespace fourd::reconstruct
