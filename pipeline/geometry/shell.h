#pragma once
// A thin closed shell around an open tube-shaped sheet (a skirt, a sleeve): the sheet is a grid
// of points, `rings` rings of `columns` points each, closed around every ring. The shell's
// outer side is the sheet moved half the thickness along its normal, the inner side half the
// thickness against it, and the two sides are joined along the first and the last ring, so the
// shell is closed, manifold and outward-oriented (a torus's topology), as the surfaces that
// inside/outside tests by ray parity need.
//
// Orientation: the sheet's outside is where its columns turn counterclockwise seen from
// beyond ring 0, looking along the tube (a skirt whose ring 0 is the waist, rings running down
// and columns counterclockwise seen from above, has its outside away from the legs).
#include <Eigen/Core>
#include <vector>

#include "pipeline/core/mesh.h"

namespace fourd {

// Vertex i of the sheet's grid: ring i / columns, column i % columns. The shell has
// 2 * rings * columns vertices: first the outer side, then the inner side, each in the sheet's
// order.
struct TubeGrid {
  int rings = 0;
  int columns = 0;
  int size() const { return rings * columns; }
  int index(int ring, int column) const { return ring * columns + column; }
  // Steps between points i and j across the sheet: along the ring (round the tube) or down
  // the columns, whichever is more.
  int steps(int i, int j) const;
  // The sheet's own triangles (not the shell's): per cell, ring by ring, (r, c), (r + 1, c),
  // (r + 1, c + 1) and (r, c), (r + 1, c + 1), (r, c + 1).
  std::vector<Tri> sheet_triangles() const;
};

// The shell's triangles (the same for every shape of the sheet). Needs rings >= 2 and
// columns >= 3; throws InputError otherwise.
std::vector<Tri> tube_shell_triangles(const TubeGrid& grid);

// The shell's vertex positions for the sheet `sheet` (grid.size() points). The normal at a
// point comes from its neighbours along the ring and along the column (one-sided at the first
// and the last ring); where those coincide, it points away from the ring's centroid. Where the
// sheet bends more sharply than the shell is thick, or comes nearer to another part of itself
// (folded onto itself), the shell thins there so that its sides do not pass through each other:
// each side within half the sheet's radius of curvature and 0.45 of the gap, the sheet midway.
std::vector<Vec3f> tube_shell_positions(const TubeGrid& grid, const std::vector<Eigen::Vector3d>& sheet,
                                        double thickness);

}  // namespace fourd
