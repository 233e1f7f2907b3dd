#pragma once
// The web package of an asset (docs/web.md, "The web package"): the same asset file
// (runtime/asset.h) with each motion space's geometry quantised and delta-coded over time, so
// that the gzip around the file (pipeline/core/gzip.h natively, the browser's
// DecompressionStream in the page) shrinks it. Lossy, with bounds the options set:
//   - input frames: positions on a grid of `position_step` per space (origin: the space's
//     bounding-box minimum), off by at most step / 2 per coordinate;
//   - input normals: directions in octahedral coordinates of `normal_bits` bits each (the
//     runtime normalises blended normals, so only the direction is kept);
//   - displacements (fp16, runtime/blend.h): multiples of `displacement_step`, decoded back to
//     fp16; a displacement whose fp16 gap exceeds twice the step comes back exactly, a smaller
//     one within the step; normal displacements likewise with `normal_displacement_step`.
// Each array is stored as zig-zag coded differences from the previous frame of the same input
// or reference (vertex by vertex), split into byte planes (all low bytes first): values that
// change slowly over time become long runs of small bytes that gzip compresses well.
// Everything else (roots, parameter maps, the graph's similarities, key textures) is stored as
// in the plain asset, so the motion graph plays the same transitions as the original asset.
#include <cstdint>

#include "pipeline/core/binary_format.h"
#include "runtime/motion_graph.h"

namespace fourd {

struct AssetPacking {
  double position_step = 2e-5;           // [m]
  double displacement_step = 2e-5;       // [m]
  int normal_bits = 12;                  // per octahedral coordinate, 8..16
  double normal_displacement_step = 1.0 / 2048;  // [unit normal]
  // Throws ConfigError for a step that is not positive and finite or bits outside 8..16.
  void check() const;
};

// The packed geometry of one space: its input frames, normals and both displacement arrays.
// Throws InputError naming the space for a value the grid cannot hold (a coordinate more than
// 2^30 steps from the origin, a displacement that is not finite).
void write_packed_geometry(BinaryWriter& w, const GraphSpace& space, const AssetPacking& packing);
// Reads what write_packed_geometry wrote into `space`, whose blend space sizes (inputs,
// references, vertices, frames, plane stride) are already read. Throws InputError naming the
// file for inconsistent sizes or values.
void read_packed_geometry(BinaryReader& r, GraphSpace* space);

}  // namespace fourd

namespace fourd {

// How far a decoded package's geometry is from the original's: the largest distance between a
// vertex of any reference mesh M_j(f) (runtime/blend.h: inputs, and the others' linear part
// plus displacement) [m], the largest angle between an input's normals [deg] and the largest
// difference of a normal displacement coordinate. Throws InputError when the two graphs'
// spaces differ in sizes.
struct PackingError {
  double position_m = 0;
  double normal_deg = 0;
  double normal_displacement = 0;
};
PackingError packing_error(const MotionGraph& original, const MotionGraph& decoded);

}  // namespace fourd
