#pragma once
// Closed surfaces as solids: scan-line voxelisation, the surface of an (edited) solid, the
// removal of thin handles by morphology on the solid, and re-meshing a surface on a fresh grid.
#include <Eigen/Core>
#include <cstdint>
#include <vector>

#include "pipeline/core/mesh.h"

namespace fourd {

// Inside/outside occupancy of a closed mesh on a regular grid: voxel (x, y, z) has its centre
// at origin + voxel * (x + 0.5, y + 0.5, z + 0.5).
struct SolidGrid {
  Eigen::Vector3d origin = Eigen::Vector3d::Zero();
  double voxel = 1;
  int nx = 0, ny = 0, nz = 0;
  std::vector<std::uint8_t> inside;  // [(z * ny + y) * nx + x]
  std::size_t index(int x, int y, int z) const {
    return (static_cast<std::size_t>(z) * ny + y) * nx + x;
  }
  Eigen::Vector3d center(int x, int y, int z) const {
    return origin + voxel * Eigen::Vector3d(x + 0.5, y + 0.5, z + 0.5);
  }
};

// Scan-line voxelisation: along every z column of voxel centres, the crossings with the
// triangles are sorted and the spans between successive pairs are filled (even-odd rule). For
// a mesh with holes a column with an odd number of crossings drops its last one. `padding`
// empty voxels surround the mesh's bounding box.
SolidGrid voxelize_solid(const Mesh& mesh, double voxel, int padding = 1);

// The zero set of the signed distance to `mesh`, sampled at the centres of `solid`'s voxels
// and signed by their occupancy (inside negative). Where the solid is the mesh's own the
// surface is the mesh's, to sub-voxel precision; where the solid was edited it follows the
// edit. Closed and manifold (the solid's border voxels must be empty).
Mesh surface_of_solid(const Mesh& mesh, const SolidGrid& solid);

// The mesh's surface without its handles thinner than a few voxels: noise tunnels of a
// reconstruction, an arm merged with the body where it touched it, or holes through a thin
// garment. Its solid, voxelised at `voxel`, is closed then opened by r voxels, else only closed
// (the opening erases a sheet a few voxels thin), for r = 1, 2, ... max_radius, and the first
// result whose largest component has no handle, holds all but 0.5 % of the result's volume
// (nothing cut off) and keeps at least `min_volume` of the input's volume is returned (its
// largest component); failing that, the one of the fewest handles, or the input itself when
// no result has fewer handles than it.
Mesh remove_small_handles(const Mesh& mesh, double voxel, int max_radius,
                          double min_volume = 0.98);

// The same closed surface with fresh connectivity: the zero set of its signed distance sampled
// on a grid of `voxel` shifted by `offset` (a fraction of a voxel gives unrelated vertices and
// triangles). With noise_sigma > 0 vertices move along their normals by Gaussian noise [m].
// The mesh must be closed and oriented outward; closed parts that overlap (a garment over a
// body) are re-meshed as their union (inside by winding number). Throws InputError on an empty mesh.
Mesh remesh_fresh(const Mesh& mesh, double voxel, const Eigen::Vector3d& offset,
                  double noise_sigma = 0, unsigned seed = 1);

}  // namespace fourd
