#pragma once
// Root motion estimated from the meshes themselves (stages get no skeleton).
//
// The world's up axis is +z and the floor is z = 0 (the studio's convention); the template
// stands upright on the floor. The "root" of a frame is a ground-plane pose (x, y, heading):
//  - position: the ground projection of the torso centroid, a stand-in for the pelvis;
//  - heading: the rotation about z that best aligns the frame's torso with the template's
//    (weighted 2D Procrustes on the horizontal coordinates), so the template's facing
//    direction is heading 0.
// The torso is picked on the template: vertices between 50 % and 80 % of the body height and
// within 12 % of the height from the body's vertical axis at that height (arms and legs swing;
// the torso carries the body's position and facing direction). A shape "with root motion
// removed" is the frame moved back by the inverse root: it sits over the origin facing +x,
// keeping its height above the floor.
#include <Eigen/Core>
#include <span>
#include <vector>

#include "pipeline/core/se2.h"

namespace fourd {

// Roots are RootTransforms (pipeline/core/se2.h): (x, y, heading), p -> R(heading) p + (x, y).

// Per-vertex weights of the torso region of `template_positions` (3 x #V), summing to 1. Falls
// back to every vertex when the region is empty (a character unlike a standing person).
std::vector<double> torso_weights(const Eigen::Matrix3Xd& template_positions);

// Body height of the template: highest minus lowest z.
double body_height(const Eigen::Matrix3Xd& template_positions);

// The root of one frame (3 x #V, template topology). `torso` from torso_weights().
RootTransform estimate_root(const Eigen::Matrix3Xd& frame, const Eigen::Matrix3Xd& template_positions,
                    std::span<const double> torso);

// The frame with `root` removed: R(-heading) (p - (x, y, 0)); z unchanged.
Eigen::Matrix3Xd remove_root(const Eigen::Matrix3Xd& frame, const RootTransform& root);
// The inverse: a root-free shape placed at `root`.
Eigen::Matrix3Xd apply_root(const Eigen::Matrix3Xd& shape, const RootTransform& root);

// Smooths a root curve in time: `passes` of the [1 2 1] / 4 filter on x, y and the unwrapped
// heading, the first and last roots kept. Alignment noise makes the per-frame torso estimate
// jitter from frame to frame; the gait's own sway (a cycle long) passes nearly unchanged.
void smooth_roots(std::vector<RootTransform>* roots, int passes);

// Roots of a whole sequence with headings unwrapped (continuous across +-pi).
std::vector<RootTransform> estimate_roots(std::span<const Eigen::Matrix3Xd> frames,
                                  const Eigen::Matrix3Xd& template_positions,
                                  std::span<const double> torso);

}  // namespace fourd
