#pragma once
// Plate difference: a per-camera model of the empty studio from its background plates, and the
// silhouette of a frame against it. The model tolerates the light changing between the plates
// and the frame (a gain per colour channel, estimated on the pixels that are surely background)
// and the performer's shadows: a pixel darker than the plate by a factor down to
// kShadowDarkest but of the plate's chromaticity is background, where a shadow of the
// performer can fall: on the floor (z = 0, the session's convention) around the rig's centre.
// Elsewhere (walls, furniture, the floor far away) a darker pixel is the performer: dark clothes
// over a grey wall are not taken for a shadow. Nor is a darker pixel whose neighbourhood hides
// the plate's texture (the frame does not correlate with the plate there): a shadow lets the
// floor's pattern show through, trousers do not.
#include <Eigen/Core>
#include <opencv2/core.hpp>
#include <string>
#include <vector>

#include "pipeline/core/camera.h"
#include "stages/segment/segment.h"

namespace fourd::segment {

struct PlateModel {
  cv::Mat mean;        // CV_32FC3 BGR, the mean of the plates [8-bit levels]
  double sigma = 0;    // sensor noise of one image, std-dev per channel [8-bit levels]
  int plates = 0;      // images the mean is of
  // CV_8UC1, nonzero where the plate shows surface the performer's shadows can fall on (the
  // floor around the rig's centre, floor_shadow_region); empty: everywhere.
  cv::Mat shadow_region;
};

// The pixels of `camera` whose ray meets the floor plane z = 0 within `radius` (horizontally) of
// `centre` (the point the cameras look at, z > 0) — CV_8UC1, 0/255. Where a ray meets no floor
// nearer (it rises, or meets the floor farther out) the plate shows a wall or far floor.
cv::Mat floor_shadow_region(const Camera& camera, const Eigen::Vector3d& centre, double radius);

// The model of one camera from its plates (BGR, all of one size). With one plate the noise is
// estimated from the plate's fine detail. Throws InputError naming `camera` when there is no
// plate or their sizes differ.
PlateModel learn_plate(const std::vector<cv::Mat>& plates, const std::string& camera);

// The gain per channel (B, G, R) that maps the plate onto the frame's background, estimated on
// pixels whose ratio to the plate is near the median's (the performer and its shadows are not).
cv::Vec3d background_gain(const cv::Mat& bgr, const PlateModel& plate);

// One silhouette (CV_8UC1, 0/255) of a BGR frame against the plate model, cleaned up like the
// chroma key's; the outline decided by the matte alpha against the plate's own colour. With
// `shadow_like`, also the background pixels that are so only by the shadow rule (clearly darker
// than the plate, of its chromaticity): a shadow, or dark clothes over a neutral background,
// which the other cameras can tell apart (ConsistencyCheck::recover). With `off_plate`, the
// pixels left out that are off the plate's colour by more than the noise, a darker shade
// included: where the performer may hide in its own colour (ConsistencyCheck::recover_hidden).
cv::Mat plate_silhouette(const cv::Mat& bgr, const PlateModel& plate,
                         const SegmentOptions& options, cv::Mat* shadow_like = nullptr,
                         cv::Mat* off_plate = nullptr);

// The final outline of a silhouette (in place), after pixels were added to it
// (recover_hidden): the pixels on either side of a contrasting outline go by their matte alpha
// against the plate and the performer's colour just inside, smoothed over the neighbours (a
// Gaussian of kOutlineBlur px), foreground at one half or more.
void refine_plate_outline(cv::Mat& mask, const cv::Mat& bgr, const PlateModel& plate);

}  // namespace fourd::segment
