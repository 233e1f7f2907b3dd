#pragma once
// Foreground segmentation of a chroma-key studio capture: per camera, a backdrop model is
// learned from the frames themselves (how green the screen and floor are, shadows included),
// then every frame is keyed, cleaned up morphologically and written as a 0/255 silhouette.
#include <opencv2/core.hpp>
#include <string>
#include <vector>

#include "pipeline/core/config.h"
#include "pipeline/core/session.h"
#include "stages/common/stage.h"

namespace fourd::segment {

struct SegmentOptions {
  int model_frames = 12;          // frames sampled per camera (over all takes) to learn the key
  double key_offset = 16;         // grey levels added to G in the keyness denominator (noise in shadows)
  int matte_radius = 3;           // window radius of local backdrop colours [px] (performer: -1)
  int open_radius = 1;            // morphological opening radius [px] against speckle
  double min_component_fraction = 0.02;  // keep components at least this fraction of the largest
  double max_hole_fraction = 0.0005;     // fill enclosed background holes up to this image fraction
  double warn_foreground_min = 0.001;    // warn when a silhouette covers less of the image
  double warn_foreground_max = 0.5;      // ... or more

  template <class V>
  void visit(V& v) {
    v("model_frames", model_frames, "frames sampled per camera to learn the key", Range{1, 10000});
    v("key_offset", key_offset, "offset of the keyness denominator [grey levels]", Range{0, 255});
    v("matte_radius", matte_radius, "window radius of the local matte colours [px]",
      Range{2, 50});
    v("open_radius", open_radius, "morphological opening radius [px]", Range{0, 20});
    v("min_component_fraction", min_component_fraction,
      "smallest kept component relative to the largest", Range{0, 1});
    v("max_hole_fraction", max_hole_fraction, "largest filled hole [fraction of the image]",
      Range{0, 1});
    v("warn_foreground_min", warn_foreground_min, "warn below this foreground fraction",
      Range{0, 1});
    v("warn_foreground_max", warn_foreground_max, "warn above this foreground fraction",
      Range{0, 1});
  }
};

// "Keyness" of each pixel of a BGR image: (G - max(R, B)) / (G + offset), high on the green
// backdrop whatever its brightness (shadows), near or below zero on the performer.
cv::Mat keyness(const cv::Mat& bgr, double offset);

// The key learned for one camera: keyness values that are surely backdrop or surely performer.
struct KeyModel {
  double foreground_below = 0;  // keyness below this: surely the performer
  double backdrop_above = 0;    // keyness above this: surely the backdrop
};

// Learns the key from sampled keyness maps: Otsu's threshold splits backdrop from performer;
// the backdrop's keyness distribution sets how sure "surely backdrop" is.
KeyModel learn_key(const std::vector<cv::Mat>& keyness_maps);

// One silhouette (CV_8UC1, 0/255, 255 = performer) from a BGR frame, cleaned up. Pixels between
// the sure classes (anti-aliased outline) are decided by their matte alpha under the linear
// mixing model C = alpha F + (1 - alpha) B, with B and F the local mean colours of the sure
// backdrop and sure performer around them: foreground when alpha >= 0.5, so the outline falls
// where the performer covers half the pixel.
cv::Mat key_silhouette(const cv::Mat& bgr, const KeyModel& key, const SegmentOptions& options);

void run_segment(const Session& session, const StageArgs& args);

}  // namespace fourd::segment
