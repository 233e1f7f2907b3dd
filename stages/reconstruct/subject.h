#pragma once
// The size of what is filmed, measured from the capture, and the scale of the subject-relative
// lengths of the options (config.h, Length) derived from it.
//
//   1. The volume the cameras share: the bounding box of the points that enough cameras see
//      (as many as the visual hull needs to carve a point: VisualHullOptions::min_views and
//      min_view_fraction), sampled on a lattice over the rig's reach.
//   2. The subject's size: the largest side of the visual hull's bounding box over that
//      volume, on a few frames spread through the session (a coarse hull, `grid` cells along
//      the volume's largest side), the median over the frames.
//   3. factor = size / kReferenceSubjectSize (1.75 m, what the defaults were tuned on),
//      rounded to a step of a geometric series (steps_per_decade; 20: 1, 1.12, 1.26, ... the
//      R20 preferred numbers), so that a subject within 6 % of the reference gets exactly
//      today's defaults, and a frame more or less measured does not change the options.
//
// The stage writes the result to reconstruct/subject.json (SubjectScale::to_json), which later
// stages can read for the same scale:
//   {"subject_size_m", "subject_height_m", "scale_factor", "reference_size_m", "measured",
//    "frames_measured", "shared_volume": {"min": [x,y,z], "max": [x,y,z]},
//    "hull_box": {"min", "max"}}
#include <Eigen/Core>
#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>
#include <vector>

#include "pipeline/core/camera.h"
#include "pipeline/core/config.h"
#include "pipeline/core/subject.h"
#include "stages/reconstruct/visual_hull.h"

namespace fourd::reconstruct {

// The options are the members visit() lists, with their help; the others are tuned values,
// not options (docs/reconstruct.md, "Advanced").
struct SubjectScaleOptions {
  double subject_size = 0;
  int sample_frames = 5;       // frames the hull is measured on, spread through the session
  int grid = 64;               // coarse hull cells along the shared volume's largest side
  int steps_per_decade = 20;   // the factor is rounded to 10^(k / steps) (0: not rounded), so
                               // that split jobs derive the same factor
  template <class V>
  void visit(V& v) {
    v("subject_size", subject_size,
      "largest extent of the subject [m], when known (0: measured from the visual hull)",
      Range{0, 1000});
  }
};

struct Box {
  Eigen::Vector3d min = Eigen::Vector3d::Zero();
  Eigen::Vector3d max = Eigen::Vector3d::Zero();
  bool empty() const { return !(max.array() > min.array()).all(); }
  Eigen::Vector3d size() const { return max - min; }
  nlohmann::json to_json() const;
};

// Cameras a point needs to be carved by the visual hull of `cameras` cameras.
int required_views(const VisualHullOptions& options, int cameras);

// The bounding box of the points seen (in front of the camera, inside its image) by at least
// `views` of `cameras`, sampled on a lattice of `cells`^3 over a box around the point closest
// to every optical axis, twice as wide as the farthest camera is from it. Empty when no lattice
// point is seen by that many.
Box shared_volume(const std::vector<Camera>& cameras, int views, int cells = 64);

// The bounding box of one frame's visual hull inside `volume`, on a coarse grid of `cells`
// along the volume's largest side (VisualHull::grid, at a quarter of that spacing around the
// hull). Empty when nothing is inside every silhouette.
Box hull_box(const std::vector<Camera>& cameras, const std::vector<cv::Mat>& silhouettes,
             const VisualHullOptions& hull, const Box& volume, int cells);


struct SubjectScale {
  double size = kReferenceSubjectSize;    // largest side of the hull's box, median [m]
  double height = kReferenceSubjectSize;  // its vertical side (z), median [m]
  double factor = 1;
  bool measured = false;                  // false: subject_size was given
  int frames_measured = 0;
  Box shared;    // the volume the cameras share
  Box hull;      // the measured frames' hull boxes together
  nlohmann::json to_json() const;
};

// The subject measured on `frames` (per frame the cameras that have a silhouette and those
// silhouettes), or given by options.subject_size. Throws InputError when it is measured and
// no frame has a hull.
SubjectScale measure_subject(const std::vector<std::vector<Camera>>& frame_cameras,
                             const std::vector<std::vector<cv::Mat>>& frame_silhouettes,
                             const VisualHullOptions& hull, const Box& shared,
                             const SubjectScaleOptions& options);

// The capture volume searched for a subject of scale `factor`: the shared volume together with
// the default volume (VisualHullOptions{}) scaled by the factor, from the floor (z = 0, z up,
// the default volume's lower side) up. On the reference rig the shared volume lies inside the
// default volume, which is then kept as it is (the same grid, the same meshes).
void derive_volume(VisualHullOptions& hull, const Box& shared, double factor);

}  // namespace fourd::reconstruct
