#pragma once
// Texture atlas and clothing of the procedural performer. Internal to the synth stage.
//
// Every vertex belongs to one chart: the torso (with neck and head), an arm, a leg or a foot.
// A chart maps the angle around its body part's axis, folded to [0, pi] (mirror-symmetric, so
// the map is continuous all the way round: no seam inside a chart), and the height or the
// length along the axis. Left and right limbs share their chart. The charts are laid out so
// that parts that meet on the body (shoulder / arm, hip / leg, ankle / foot) sit at the same
// texture rows, and the texture between them carries the colour of the junction: the few
// triangles that straddle two charts sample a clean strip of that colour.
#include <cstdint>
#include <opencv2/core.hpp>
#include <optional>
#include <vector>

#include "pipeline/core/mesh.h"
#include "stages/synth/body_model.h"

namespace fourd::synth::detail {

enum class Chart { kTorso, kArm, kLeg, kFoot };

struct ChartRef {
  Chart chart = Chart::kTorso;
  int side = 0;  // 0 = left, 1 = right (limbs)
};

// Texture coordinates of a rest-pose point of the given chart (OBJ convention, v up).
Vec2f chart_uv(const BodyModel& body, const ChartRef& ref, const Eigen::Vector3d& point);

// A skirt's chart: u the folded angle around the waist (0 at the front, as the torso's), v the
// distance down the cloth from the waist, in the atlas's rows above those the legs use. The
// shape as cut makes the pattern's scale on the cloth uniform.
struct SkirtChart {
  double waist_radius = 0;  // mean radius of the waistband [m]
  double length = 0;        // waist to hem along the cloth [m]
  double flare = 0;         // half-angle of the cut's cone [rad]
};

// Texture coordinates of the skirt at folded angle `phi` in [0, pi] and `down` in [0, 1] (the
// waist to the hem).
Vec2f skirt_uv(double phi, double down);

// The clothing texture (CV_8UC3, BGR) for the atlas: colours and patterns from the seed. The
// wardrobe leaves out garments near the studio's key colour (`key`, RGB in [0, 1]), as a costume
// department dresses a performer for a blue or a green screen; no key: the whole wardrobe. With
// a skirt, its chart is painted too (a colour of its own, from the seed); the rest of the
// texture is the same as without.
cv::Mat paint_clothing(const BodyModel& body, int size, std::uint64_t seed,
                       const std::optional<Eigen::Vector3d>& key = std::nullopt,
                       const std::optional<SkirtChart>& skirt = std::nullopt);

}  // namespace fourd::synth::detail
