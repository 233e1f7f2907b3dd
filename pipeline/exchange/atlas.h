#pragma once
// The template's UV atlas as the texture stage hands it on (texture/atlas.ply, atlas.json):
// its charts, per-corner texture coordinates and the texels bound to the surface points they
// show. How the atlas is built is stages/texture/atlas.h's.
#include <Eigen/Core>
#include <vector>

#include "pipeline/core/mesh.h"

namespace fourd {

struct Chart {
  std::vector<int> faces;   // template faces in this chart
  Eigen::Vector2d offset;   // texel position of the chart's box corner (x right, y down)
  Eigen::Vector2d size;     // box size [texels], gutter excluded
  double area = 0;          // surface area [m^2]
  double stretch = 1;       // Sander's L2 stretch of the chart (1 = isometric)
};

struct Atlas {
  int resolution = 0;
  int gutter = 0;
  // Per-corner texture coordinates: face f's corner k has uvs[uv_triangles[f][k]], OBJ
  // convention ((0,0) the bottom-left corner of the image, v up).
  std::vector<Vec2f> uvs;
  std::vector<Tri> uv_triangles;     // #F
  std::vector<int> face_chart;       // #F: chart of each face
  std::vector<Chart> charts;
  double texels_per_metre = 0;       // common density of every chart
  double stretch = 1;                // area-weighted L2 stretch over all charts
  double max_stretch = 1;            // worst chart
  int flipped_faces = 0;             // faces with negative area in the plane (should be 0)
  int splits = 0;                    // charts split because they failed a test

  // Texel coordinates (x right, y down, texel centres at +0.5) of a UV.
  Eigen::Vector2d texel(const Vec2f& uv) const {
    return {uv.x() * resolution, (1.0 - uv.y()) * resolution};
  }
};

// The texels of the atlas bound to the surface: each texel whose centre lies in a triangle, or
// within `reach` texels outside its chart's border (those take the nearest point of the
// triangle, so bilinear lookups along chart borders read surface colours, not gutter).
struct TexelMap {
  int resolution = 0;
  std::vector<int> sample_of;          // res*res: texel (y*res + x) -> sample index, -1 if none
  std::vector<int> texel;              // per sample: y*res + x
  std::vector<int> face;               // per sample: triangle
  std::vector<Eigen::Vector3f> bary;   // per sample: barycentric coordinates in the triangle
  int overlapping = 0;                 // texel centres strictly inside triangles of two charts
                                       // or of one chart folded over itself (should be 0)
  std::size_t size() const { return texel.size(); }
};
TexelMap map_texels(const Atlas& atlas, const std::vector<Tri>& triangles, double reach = 0.75);

}  // namespace fourd
