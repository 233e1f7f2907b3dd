#pragma once
// The UV atlas of the template: the surface cut into charts of low distortion, each flattened
// (parameterize.h) and packed into one square texture with gutters between charts, and the
// texels of that texture bound to the surface points they show.
//
// Charts grow from seed faces while a face's normal stays within max_chart_angle of the
// chart's mean normal (so no chart wraps around a limb). A chart that is not a topological
// disc, folds over when flattened, or stretches more than max_stretch (Sander's L2 stretch) is
// split in two across its longest extent, until every chart passes. Packing: charts rotated to
// their principal axes, scaled to one common texel density, placed on shelves; the density is
// the largest at which everything fits.
#include <Eigen/Core>
#include <array>
#include <string>
#include <vector>

#include "pipeline/core/config.h"
#include "pipeline/core/mesh.h"
#include "pipeline/exchange/atlas.h"

namespace fourd::texture {

// The options are the members visit() lists, with their help; the others are tuned values,
// not options (docs/texture.md, "Advanced").
struct AtlasOptions {
  int resolution = 1024;
  int gutter = 4;                // empty texels between two charts (at least 2)
  double max_chart_angle = 55;   // largest angle between a face normal and its chart's [deg]
  double max_stretch = 1.15;     // largest L2 stretch of a chart (1 = no distortion)
  std::string method = "lscm";

  template <class V>
  void visit(V& v) {
    v("resolution", resolution, "texels per side of the (square) texture", Range{16, 16384});
    v("method", method, "chart flattening: lscm (conformal) or arap (as rigid as possible)");
  }
  void check() const;
};


// Builds the atlas of `mesh` (its positions and triangles; other attributes are ignored).
// Throws InputError for a mesh without triangles, ConfigError when the charts cannot be packed
// at the resolution (more charts than texels), SolverError when a chart cannot be flattened.
Atlas build_atlas(const Mesh& mesh, const AtlasOptions& options);

// `mesh` with the atlas's per-corner UVs (for writing texture/atlas.ply and rendering).
Mesh with_atlas_uvs(const Mesh& mesh, const Atlas& atlas);


// Neighbour of every face across each of its edges (edge k runs from corner k to k+1); -1 on
// a border or a non-manifold edge (more than two faces).
std::vector<std::array<int, 3>> face_neighbours(const std::vector<Tri>& triangles);

// Area-weighted L2 stretch (Sander et al. 2001) of the map from the plane to the surface over
// `faces`, after scaling the plane so both have the same area; 1 for an isometry. `flipped`
// (optional) counts faces whose plane triangle has negative signed area.
double l2_stretch(const std::vector<Eigen::Vector3d>& positions,
                  const std::vector<Eigen::Vector2d>& uv, const std::vector<Tri>& triangles,
                  int* flipped = nullptr);

}  // namespace fourd::texture
