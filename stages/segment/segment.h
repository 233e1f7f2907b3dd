#pragma once
// Foreground segmentation of a studio capture, by one of three methods (stages.segment.method):
//
//   chroma  a chroma screen of any colour: per camera, the backdrop's colour is learned from the
//           frames themselves (the most common saturated hue), then every pixel's keyness (how
//           much of it lies along the backdrop's chroma direction) is split into performer and
//           backdrop, the outline decided by a matte;
//   plate   any static background: per camera, a background model from the plates of the empty
//           studio (plates/<camera>/<index>.png), compared with each frame after a global gain
//           (flicker, exposure), shadows (darker, same chromaticity) counted as background;
//   masks   supplied silhouettes (masks/<take>/<camera>/<frame>.png), checked and copied.
//
// "auto" picks plate when plates/ exists, else masks when masks/ exists, else chroma. Every
// method's silhouettes are cleaned up the same way and checked: a frame whose foreground
// fraction is implausible, or whose silhouette in a camera is not explained by the visual hull
// of all cameras (consistency.h), is a warning naming take, camera and frame, in the log and in
// segment/report.json.
#include <filesystem>
#include <opencv2/core.hpp>
#include <string>
#include <vector>

#include "pipeline/core/config.h"
#include "pipeline/core/session.h"
#include "stages/common/stage.h"

namespace fourd::segment {

// The options are the members visit() lists, with their help; the others are tuned values,
// not options (docs/segment.md, "Advanced").
struct SegmentOptions {
  std::string method = "auto";
  int model_frames = 12;          // frames sampled per camera (over all takes) to learn the key
  double key_offset = 16;         // grey levels added to the keyness denominator (noise in shadows)
  int matte_radius = 3;           // window radius of local backdrop colours [px] (performer: -1)
  int open_radius = 1;
  double min_component_fraction = 0.02;  // keep components at least this fraction of the largest
  double max_hole_fraction = 0.0005;
  double warn_foreground_min = 0.001;    // warn when a silhouette covers less of the image
  double warn_foreground_max = 0.5;      // ... or more

  template <class V>
  void visit(V& v) {
    v("method", method,
      "auto (plate if plates/ exists, else masks if masks/ exists, else chroma) | chroma | plate "
      "| masks");
    v("open_radius", open_radius, "morphological opening radius against speckle [px]",
      Range{0, 20});
    v("max_hole_fraction", max_hole_fraction,
      "fill enclosed background holes up to this fraction of the image", Range{0, 1});
  }
  void check() const;
};

// ---- chroma ---------------------------------------------------------------------------------

// A chroma backdrop as one camera sees it.
struct Backdrop {
  cv::Vec3d direction;    // unit chroma direction in RGB, orthogonal to grey (1, 1, 1)
  cv::Vec3d rgb;          // mean colour of the backdrop's pixels [8-bit levels]
  double hue_deg = 0;     // angle of `direction` in the chroma plane: red 0, green 120, blue 240
  double fraction = 0;    // of the sampled pixels that have the backdrop's hue
};

// The chroma direction of a pure hue (degrees, red 0, green 120, blue 240).
cv::Vec3d chroma_direction(double hue_deg);

// Learns the backdrop from sampled BGR frames of one camera: the most common hue among the
// saturated pixels (a histogram over the chroma plane), refined to the mean chroma of the pixels
// near it. Throws InputError naming `camera` when no saturated hue covers enough of the frames
// (not a chroma studio: plates/ or masks/ are needed).
Backdrop learn_backdrop(const std::vector<cv::Mat>& frames, const std::string& camera);

// "Keyness" of each pixel of a BGR image: how much of the pixel's colour lies along the
// backdrop's chroma direction u, beyond its other chroma component v, relative to its
// brightness along u. For a pure green backdrop it is (G - max(R, B)) / (G + offset); in
// general (sqrt(6)/2 C.u - |C.v|/sqrt(2)) / (max(mean(C) + sqrt(6)/3 C.u, 0) + offset), high on
// the backdrop whatever its brightness (shadows), near or below zero on the performer.
cv::Mat keyness(const cv::Mat& bgr, const Backdrop& backdrop, double offset);

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
cv::Mat key_silhouette(const cv::Mat& bgr, const Backdrop& backdrop, const KeyModel& key,
                       const SegmentOptions& options);

// Decides the pixels between the sure classes (CV_8UC1 masks) by their matte alpha under
// C = alpha F + (1 - alpha) B: F the mean colour of the sure foreground within `radius` - 1 px,
// B the mean colour of the sure background within `radius` px or, when `background` (CV_32FC3
// BGR) is given, the background's own colour there (a plate). Pixels with no sure neighbours to
// compare take `undecided_fg`. Returns the 0/255 mask before clean-up.
cv::Mat matte_outline(const cv::Mat& bgr, const cv::Mat& sure_fg, const cv::Mat& sure_bg,
                      const cv::Mat& background, const cv::Mat& undecided_fg, int radius);

// The clean-up every method shares: opening against speckle, the largest components kept,
// small enclosed holes filled (in place).
void clean_up(cv::Mat& mask, const SegmentOptions& options);

// ---- masks ----------------------------------------------------------------------------------

// Reads a supplied mask (8-bit grey, 0 background / 255 performer; other values are thresholded
// at 128) and checks its size against the camera's. InputError naming the file, camera and frame
// when it is missing, not decodable, or of another size.
cv::Mat read_supplied_mask(const std::filesystem::path& path, const std::string& camera,
                           int width, int height, int frame);

// ---- method choice --------------------------------------------------------------------------

struct MethodChoice {
  std::string method;  // chroma | plate | masks
  std::string reason;  // why, for the log and the report
};

// The method `requested` (options.method) resolves to in the session at `root`: "auto" looks for
// plates/ (a folder with a camera folder in it), then masks/ (a folder with a take folder).
MethodChoice choose_method(const std::filesystem::path& root, const std::string& requested);

void run_segment(const Session& session, const StageArgs& args);

}  // namespace fourd::segment
