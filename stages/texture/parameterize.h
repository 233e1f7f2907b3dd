#pragma once
// Flattening of one atlas chart with CGAL's Surface_mesh_parameterization (LSCM or ARAP).
// Kept in its own .cpp: it is the only CGAL-heavy code of the texture stage.
#include <Eigen/Core>
#include <string>
#include <vector>

#include "pipeline/core/mesh.h"

namespace fourd::texture {

enum class FlattenMethod {
  kLscm,  // least-squares conformal maps, two pinned border vertices (angle-preserving)
  kArap,  // as-rigid-as-possible, started from LSCM (also preserves area)
};

// "lscm" / "arap"; ConfigError naming `field` for anything else.
FlattenMethod parse_flatten_method(const std::string& name, const std::string& field);

// Flattens a chart given as its own small mesh: `positions` (#V, metres) and `triangles`
// (#F, indices into positions) must form one manifold topological disc (one border loop).
// Returns false, leaving `uv` untouched, when CGAL cannot build or parameterise the chart (not a
// disc, singular system); the caller splits the chart then. `uv` gets #V points in the plane,
// in the chart's own (arbitrary) similarity frame.
bool flatten_chart(const std::vector<Eigen::Vector3d>& positions, const std::vector<Tri>& triangles,
                   FlattenMethod method, std::vector<Eigen::Vector2d>* uv);

}  // namespace fourd::texture
