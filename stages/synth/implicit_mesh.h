#pragma once
// Sampling an implicit function on a grid. Internal to the synth stage.
#include <Eigen/Core>
#include <functional>

#include "pipeline/core/isosurface.h"
#include "pipeline/core/mesh.h"

namespace fourd::synth::detail {

// Samples `field` on the grid covering [lo, hi] with the given spacing (in parallel; the
// result does not depend on the thread count).
ScalarGrid sample_field(const std::function<double(const Eigen::Vector3d&)>& field,
                        const Eigen::Vector3d& lo, const Eigen::Vector3d& hi, double spacing);

// The same for a signed-distance-like field (changing by at most `lipschitz` per metre):
// evaluated exactly only near its zero set (found on a 4x coarser grid); elsewhere the samples
// only carry the right sign (interpolated from the coarse grid). Much faster, and contouring
// it gives the same surface.
ScalarGrid sample_distance_field(const std::function<double(const Eigen::Vector3d&)>& field,
                                 const Eigen::Vector3d& lo, const Eigen::Vector3d& hi, double spacing,
                                 double lipschitz);

}  // namespace fourd::synth::detail
