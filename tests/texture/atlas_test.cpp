// The UV atlas: charts that do not overlap, bounded distortion, every face mapped.
#include <gtest/gtest.h>

#include <Eigen/Geometry>

#include "pipeline/core/error.h"
#include "stages/texture/atlas.h"
#include "tests/test_shapes.h"

namespace fourd::texture {
namespace {

// The properties every atlas must have, whatever the mesh.
void expect_valid_atlas(const Mesh& mesh, const Atlas& atlas, const AtlasOptions& options) {
  ASSERT_EQ(atlas.uv_triangles.size(), mesh.triangles.size());
  ASSERT_EQ(atlas.face_chart.size(), mesh.triangles.size());
  for (std::size_t f = 0; f < mesh.triangles.size(); ++f) {
    ASSERT_GE(atlas.face_chart[f], 0) << "face " << f << " has no chart";
    for (int k = 0; k < 3; ++k) {
      const Vec2f& uv = atlas.uvs[atlas.uv_triangles[f][k]];
      EXPECT_TRUE(uv.x() >= 0 && uv.x() <= 1 && uv.y() >= 0 && uv.y() <= 1) << "face " << f;
    }
  }
  EXPECT_EQ(atlas.flipped_faces, 0);
  EXPECT_LE(atlas.max_stretch, options.max_stretch);
  EXPECT_GE(atlas.stretch, 1.0 - 1e-9);  // L2 stretch is at least 1

  // Charts' boxes, gutters included, are disjoint and hold their chart's UVs.
  const double half = 0.5 * atlas.gutter;
  std::vector<Eigen::AlignedBox2d> boxes;
  for (const Chart& c : atlas.charts) {
    boxes.emplace_back(c.offset - Eigen::Vector2d::Constant(half),
                       c.offset + c.size + Eigen::Vector2d::Constant(half));
  }
  for (std::size_t a = 0; a < boxes.size(); ++a) {
    for (std::size_t b = a + 1; b < boxes.size(); ++b) {
      const Eigen::AlignedBox2d overlap = boxes[a].intersection(boxes[b]);
      EXPECT_TRUE(overlap.isEmpty() || overlap.volume() < 1e-9) << "charts " << a << " and " << b;
    }
  }
  for (std::size_t f = 0; f < mesh.triangles.size(); ++f) {
    const Chart& c = atlas.charts[atlas.face_chart[f]];
    const Eigen::AlignedBox2d inner(c.offset - Eigen::Vector2d::Constant(1e-3),
                                    c.offset + c.size + Eigen::Vector2d::Constant(1e-3));
    for (int k = 0; k < 3; ++k) {
      EXPECT_TRUE(inner.contains(atlas.texel(atlas.uvs[atlas.uv_triangles[f][k]]))) << "face " << f;
    }
  }
  // No texel centre strictly inside two triangles.
  const TexelMap texels = map_texels(atlas, mesh.triangles);
  EXPECT_EQ(texels.overlapping, 0);
  EXPECT_GT(texels.size(), 0u);
}

TEST(Atlas, BoxHasOneUndistortedChartPerSide) {
  const Mesh box = test::make_box(Vec3f(1.0f, 0.5f, 0.25f));
  AtlasOptions options;
  options.resolution = 256;
  const Atlas atlas = build_atlas(box, options);
  EXPECT_EQ(atlas.charts.size(), 6u);
  EXPECT_NEAR(atlas.stretch, 1.0, 1e-6);
  EXPECT_NEAR(atlas.max_stretch, 1.0, 1e-6);
  expect_valid_atlas(box, atlas, options);
  // One density for every chart: each side's box is its size in metres times the density.
  for (const Chart& c : atlas.charts) {
    EXPECT_NEAR(c.size.x() * c.size.y(), c.area * atlas.texels_per_metre * atlas.texels_per_metre,
                1e-6 * c.size.x() * c.size.y());
  }
}

TEST(Atlas, SphereChartsDoNotOverlapAndStretchIsBounded) {
  const Mesh sphere = test::make_icosphere(3, 0.5f);  // 1280 triangles
  AtlasOptions options;
  options.resolution = 512;
  const Atlas atlas = build_atlas(sphere, options);
  EXPECT_GT(atlas.charts.size(), 4u);  // a sphere cannot be one chart within 55 degrees
  expect_valid_atlas(sphere, atlas, options);
  // Packing uses a fair part of the square (shelves of boxes; charts are not rectangles).
  const TexelMap texels = map_texels(atlas, sphere.triangles);
  EXPECT_GT(static_cast<double>(texels.size()) / (512.0 * 512.0), 0.3);
}

TEST(Atlas, ArapFlatteningAlsoGivesAValidAtlas) {
  const Mesh sphere = test::make_icosphere(2, 0.5f);
  AtlasOptions options;
  options.resolution = 256;
  options.method = "arap";
  const Atlas atlas = build_atlas(sphere, options);
  expect_valid_atlas(sphere, atlas, options);
}

TEST(Atlas, TighterStretchBoundGivesMoreCharts) {
  const Mesh sphere = test::make_icosphere(3, 0.5f);
  AtlasOptions loose, tight;
  loose.max_chart_angle = tight.max_chart_angle = 80;
  loose.max_stretch = 2.0;
  tight.max_stretch = 1.02;
  const Atlas a = build_atlas(sphere, loose);
  const Atlas b = build_atlas(sphere, tight);
  EXPECT_GT(b.charts.size(), a.charts.size());
  EXPECT_LE(b.max_stretch, 1.02);
  expect_valid_atlas(sphere, b, tight);
}

TEST(Atlas, StretchOfAKnownMap) {
  const std::vector<Eigen::Vector3d> p = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}};
  const std::vector<Tri> t = {Tri(0, 1, 2)};
  // Isometric and uniformly scaled maps have no stretch.
  EXPECT_NEAR(l2_stretch(p, {{0, 0}, {1, 0}, {0, 1}}, t), 1.0, 1e-12);
  EXPECT_NEAR(l2_stretch(p, {{0, 0}, {3, 0}, {0, 3}}, t), 1.0, 1e-12);
  // Twice as wide, area equalised: singular values sqrt(2) and 1/sqrt(2).
  EXPECT_NEAR(l2_stretch(p, {{0, 0}, {2, 0}, {0, 1}}, t), std::sqrt(1.25), 1e-12);
  int flipped = 0;
  l2_stretch(p, {{0, 0}, {0, 1}, {1, 0}}, t, &flipped);
  EXPECT_EQ(flipped, 1);
}

TEST(Atlas, BadOptionsAndInputAreRejected) {
  AtlasOptions options;
  options.method = "harmonic";
  EXPECT_THROW(options.check(), ConfigError);
  EXPECT_THROW(build_atlas(Mesh{}, AtlasOptions{}), InputError);
  // Far too many charts for the texture: a clear ConfigError, not a broken atlas.
  AtlasOptions tiny;
  tiny.resolution = 16;
  tiny.gutter = 8;
  EXPECT_THROW(build_atlas(test::make_icosphere(3, 0.5f), tiny), ConfigError);
}

}  // namespace
}  // namespace fourd::texture
