#pragma once
// Geodesic distances along mesh edges (Dijkstra), grown from several sources in turn.
#include <vector>

#include "pipeline/core/mesh.h"

namespace fourd {

// Dijkstra along mesh edges (`rings`: neighbours of every vertex) from `source`, lowering
// `dist` where it finds shorter paths (so repeated calls give the distance to the nearest
// source) and recording `source_id` in `owner` there. Vertices farther than `radius` are not
// expanded. Returns the vertices it reached.
std::vector<int> geodesic_update(const Mesh& mesh, const std::vector<std::vector<int>>& rings,
                                 int source, int source_id, double radius,
                                 std::vector<double>& dist, std::vector<int>& owner);

}  // namespace fourd
