// Baking: a sphere with a known texture, seen by known cameras, is textured back.
#include <gtest/gtest.h>

#include <functional>
#include <opencv2/imgproc.hpp>

#include "pipeline/core/error.h"
#include "stages/texture/atlas.h"
#include "stages/texture/bake.h"
#include "pipeline/render/textured_render.h"
#include "tests/texture/textured_scene.h"

namespace fourd::texture {
namespace {

struct SphereScene {
  Mesh sphere = test::make_uv_sphere(Eigen::Vector3f::Zero(), 0.5f, 40, 80);
  cv::Mat truth = test::smooth_texture();
  Atlas atlas;
  TexelMap texels;

  explicit SphereScene(int resolution = 512) {
    AtlasOptions options;
    options.resolution = resolution;
    atlas = build_atlas(sphere, options);
    texels = map_texels(atlas, sphere.triangles);
  }

  std::vector<View> views(const std::vector<Camera>& cameras) const {
    const MeshRenderer renderer(sphere, truth);
    std::vector<View> out;
    for (const Camera& c : cameras) out.push_back({&c, test::record(renderer, c)});
    return out;
  }

  // PSNR of the baked texture against the true colour at each texel's surface point, over
  // texels some camera saw.
  double texel_psnr(const BakedTexture& baked, const std::function<bool(int)>& use_face = {}) const {
    ImageError error;
    for (std::size_t s = 0; s < texels.size(); ++s) {
      if (use_face && !use_face(texels.face[s])) continue;
      const int y = texels.texel[s] / atlas.resolution, x = texels.texel[s] % atlas.resolution;
      if (baked.unseen.at<std::uint8_t>(y, x)) continue;
      const Tri& t = sphere.triangles[texels.face[s]];
      const Vec2f uv = texels.bary[s][0] * sphere.uvs[t[0]] + texels.bary[s][1] * sphere.uvs[t[1]] +
                       texels.bary[s][2] * sphere.uvs[t[2]];
      const Eigen::Vector3f want = sample_bilinear(truth, uv.x() * truth.cols, (1 - uv.y()) * truth.rows);
      const cv::Vec3f got = baked.color.at<cv::Vec3f>(y, x);
      for (int ch = 0; ch < 3; ++ch) {
        const double d = 255.0 * (got[ch] - want[ch]);
        error.sum_squared += d * d;
      }
      error.values += 3;
    }
    return error.psnr_db();
  }
};

TEST(Bake, SphereFromKnownCamerasReproducesItsTexture) {
  const SphereScene scene;
  // Two rings, above and below the equator, so every part of the sphere is seen.
  std::vector<Camera> cameras = test::camera_ring(6, 2.0, 1.0, "up");
  for (const Camera& c : test::camera_ring(6, 2.0, -1.0, "down", 0.5)) cameras.push_back(c);
  const BakedTexture baked = bake_texture(scene.atlas, scene.texels, scene.sphere.positions,
                                          scene.sphere.triangles, scene.views(cameras), BakeOptions{});
  EXPECT_EQ(baked.texels, static_cast<int>(scene.texels.size()));
  EXPECT_LT(baked.unseen_texels, baked.texels / 100);  // nearly everything seen
  for (int n : baked.texels_per_view) EXPECT_GT(n, 0);
  const double psnr = scene.texel_psnr(baked);
  EXPECT_GT(psnr, 30.0);

  // Rendered into a camera that took no part in the bake, it looks like the true sphere.
  const Camera held_out = test::camera_ring(1, 2.2, 0.3, "held", 0.3).front();
  const MeshRenderer truth_renderer(scene.sphere, scene.truth);
  const MeshRenderer baked_renderer(with_atlas_uvs(scene.sphere, scene.atlas), baked.color);
  const RenderedView want = truth_renderer.render(held_out);
  const RenderedView got = baked_renderer.render(held_out);
  cv::Mat recorded;
  want.image.convertTo(recorded, CV_8UC3, 255.0);
  cv::Mat inside;
  cv::erode(want.mask & got.mask, inside, cv::Mat());  // the outline mixes in the backdrop
  EXPECT_GT(cv::countNonZero(inside), 5000);
  EXPECT_GT(image_error(got.image, recorded, inside).psnr_db(), 30.0);
}

TEST(Bake, UnseenTexelsAreMarkedAndFilledFromTheirSurroundings) {
  const SphereScene scene(256);
  // One ring below the equator: the top of the sphere is seen by no camera.
  const std::vector<Camera> cameras = test::camera_ring(6, 2.0, -0.8);
  const BakedTexture baked = bake_texture(scene.atlas, scene.texels, scene.sphere.positions,
                                          scene.sphere.triangles, scene.views(cameras), BakeOptions{});
  EXPECT_GT(baked.unseen_texels, baked.texels / 20);
  EXPECT_EQ(cv::countNonZero(baked.unseen), baked.unseen_texels);
  // Filled texels take colours from the seen surface: inside the range of the seen colours,
  // never the black of an empty texel.
  cv::Mat seen_mask = ~baked.unseen;
  for (std::size_t s = 0; s < scene.texels.size(); ++s) seen_mask.data[scene.texels.texel[s]] &= 255;
  double lo[3], hi[3];
  std::vector<cv::Mat> channels;
  cv::split(baked.color, channels);
  for (int ch = 0; ch < 3; ++ch) {
    cv::Mat seen_surface = seen_mask.clone();
    cv::minMaxLoc(channels[ch], &lo[ch], &hi[ch], nullptr, nullptr, seen_surface);
  }
  int unseen_checked = 0;
  for (std::size_t s = 0; s < scene.texels.size(); ++s) {
    const int t = scene.texels.texel[s];
    if (!baked.unseen.data[t]) continue;
    const cv::Vec3f c = baked.color.at<cv::Vec3f>(t / 256, t % 256);
    for (int ch = 0; ch < 3; ++ch) {
      EXPECT_GE(c[ch], lo[ch] - 1e-4);
      EXPECT_LE(c[ch], hi[ch] + 1e-4);
    }
    EXPECT_GT(c[0] + c[1] + c[2], 0.05f);
    ++unseen_checked;
  }
  EXPECT_EQ(unseen_checked, baked.unseen_texels);
  // What was seen is still right.
  EXPECT_GT(scene.texel_psnr(baked), 30.0);
}

TEST(Bake, OccludedCamerasDoNotPaintTheSurfaceBehind) {
  // A small sphere between camera 0 and the big sphere hides the big sphere's cap around +x
  // from camera 0, the camera that faces it straight on (and would weigh most). Only the
  // cameras at +-45 degrees see that cap; with visibility its colours stay the big sphere's.
  SphereScene scene(256);
  Mesh both = scene.sphere;
  const Mesh blocker = test::make_uv_sphere(Eigen::Vector3f(1.1f, 0, 0), 0.2f, 10, 20);
  const int offset = static_cast<int>(both.positions.size());
  const int big_faces = static_cast<int>(both.triangles.size());
  for (const Vec3f& p : blocker.positions) both.positions.push_back(p);
  for (const Vec2f& uv : blocker.uvs) both.uvs.push_back(uv);
  for (const Tri& t : blocker.triangles) both.triangles.push_back(t + Tri::Constant(offset));
  AtlasOptions options;
  options.resolution = 256;
  scene.atlas = build_atlas(both, options);
  scene.texels = map_texels(scene.atlas, both.triangles);
  scene.sphere = both;
  const std::vector<Camera> cameras = test::camera_ring(8, 2.5, 0.0);
  const std::vector<View> views = scene.views(cameras);
  const BakedTexture baked = bake_texture(scene.atlas, scene.texels, both.positions, both.triangles,
                                          views, BakeOptions{});
  auto hidden_cap = [&](int face) {
    if (face >= big_faces) return false;
    const Tri& t = both.triangles[face];
    return (both.positions[t[0]] + both.positions[t[1]] + both.positions[t[2]]).x() / 3 > 0.42f;
  };
  EXPECT_GT(scene.texel_psnr(baked, hidden_cap), 28.0);
}

TEST(Bake, NoCameraSeeingTheSurfaceIsAnInputError) {
  const SphereScene scene(64);
  // Cameras looking away from the sphere.
  std::vector<Camera> cameras = test::camera_ring(2, 3.0, 0.0);
  for (Camera& c : cameras) {
    c.camera_from_world = look_at(c.center(), 2 * c.center(), Eigen::Vector3d::UnitZ());
  }
  std::vector<View> views;
  for (const Camera& c : cameras) views.push_back({&c, cv::Mat(240, 320, CV_8UC3, cv::Scalar(0, 0, 255))});
  EXPECT_THROW(bake_texture(scene.atlas, scene.texels, scene.sphere.positions, scene.sphere.triangles,
                            views, BakeOptions{}),
               InputError);
}

}  // namespace
}  // namespace fourd::texture
