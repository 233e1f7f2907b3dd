#pragma once
// Shape similarity of frames (Huang et al. 2011, "Global temporal registration of multiple
// non-rigid surface sequences"): a volumetric shape histogram per frame — the fraction of the
// solid's volume in each bin of shells around its centroid x elevation bands x azimuth sectors
// about the vertical axis — compared with the L2 distance minimised over rotations about the
// vertical axis (cyclic shifts of the sectors). Translation-invariant by construction, and
// invariant to the performer's heading.
#include <Eigen/Core>
#include <cstdint>
#include <vector>

#include "pipeline/core/config.h"
#include "pipeline/core/mesh.h"
#include "pipeline/geometry/solid.h"

namespace fourd::align {

// Tuned values, not options (docs/align.md, "Advanced"); internal_lengths() lists the lengths
// scaled to the subject.
struct DescriptorOptions {
  double voxel = 0.02;   // voxel edge of the solid's occupancy grid [m]
  double radius = 1.2;   // outer radius of the last shell [m]; farther voxels count in it
  int shells = 12;       // radial shells
  int elevations = 8;    // elevation bands, equal in solid angle
  int sectors = 16;      // azimuth sectors about the up axis
  int up_axis = 2;       // 0 = x, 1 = y, 2 = z (every session is z-up)
  template <class V>
  void internal_lengths(V& v) {
    v("voxel", voxel, "", Length{2e-05, 2});
    v("radius", radius, "", Length{0.0005, 1000});
  }
};

struct ShapeDescriptor {
  std::vector<float> bins;  // [(shell * elevations + band) * sectors + sector], sums to 1
  Eigen::Vector3d centroid = Eigen::Vector3d::Zero();  // of the solid volume [m]
  double volume = 0;                                   // [m^3]
};

ShapeDescriptor compute_shape_descriptor(const Mesh& mesh, const DescriptorOptions& options);

struct ShapeDistance {
  double value = 0;  // L2 distance between the histograms after the best rotation
  int shift = 0;     // sectors: rotating `b` by shift * 360 / sectors degrees about the up
                     // axis (right-handed) makes it most like `a`
};

ShapeDistance shape_distance(const ShapeDescriptor& a, const ShapeDescriptor& b,
                             const DescriptorOptions& options);

// Every pair: value(i, j) = value(j, i); shift(i, j) = -shift(j, i) rotates j onto i.
struct DistanceMatrix {
  Eigen::MatrixXd value;
  Eigen::MatrixXi shift;
};
DistanceMatrix pairwise_shape_distances(const std::vector<ShapeDescriptor>& descriptors,
                                        const DescriptorOptions& options);

}  // namespace fourd::align
