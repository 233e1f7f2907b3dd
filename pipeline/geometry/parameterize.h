#pragma once
// Flattening of one atlas chart with CGAL's Surface_mesh_parameterization (LSCM or ARAP), kept
// in parameterize.cpp: the texture stage's atlas flattens its charts with it.
#include <Eigen/Core>
#include <vector>

#include "pipeline/core/mesh.h"

namespace fourd {

enum class FlattenMethod {
  kLscm,  // least-squares conformal maps, two pinned border vertices (angle-preserving)
  kArap,  // as-rigid-as-possible, started from LSCM (also preserves area)
};

// Flattens a chart given as its own small mesh: `positions` (#V, metres) and `triangles`
// (#F, indices into positions) must form one manifold topological disc (one border loop).
// Returns false, leaving `uv` untouched, when CGAL cannot build or parameterise the chart (not a
// disc, singular system); the caller splits the chart then. `uv` gets #V points in the plane,
// in the chart's own (arbitrary) similarity frame.
bool flatten_chart(const std::vector<Eigen::Vector3d>& positions, const std::vector<Tri>& triangles,
                   FlattenMethod method, std::vector<Eigen::Vector2d>* uv);

}  // namespace fourd
