#include "stages/synth/render.h"

#include <fmt/format.h>
#include <gtest/gtest.h>
#include <tbb/global_control.h>

#include <cmath>
#include <cstdlib>
#include <numbers>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "pipeline/core/error.h"
#include "tests/synth/uv_sphere.h"

namespace fourd::synth {
namespace {

using test::checker_texture;
using test::make_uv_sphere;

constexpr float kRadius = 0.5f;

RigOptions test_rig() {
  RigOptions rig;
  rig.count = 4;
  rig.start_angle = 10;
  return rig;
}

StudioOptions quiet_studio() {
  StudioOptions o;
  o.noise_sigma = 0;
  return o;
}

// Nearest positive hit of the ray with a sphere, or -1.
double ray_sphere(const Ray& ray, const Eigen::Vector3d& c, double r, double* cos_incidence) {
  const Eigen::Vector3d oc = ray.origin - c;
  const double b = oc.dot(ray.direction);
  const double disc = b * b - (oc.squaredNorm() - r * r);
  if (disc < 0) return -1;
  const double t = -b - std::sqrt(disc);
  if (t <= 0) return -1;
  if (cos_incidence) {
    const Eigen::Vector3d n = (ray.origin + t * ray.direction - c).normalized();
    *cos_incidence = -n.dot(ray.direction);
  }
  return t;
}

cv::Mat dilate1(const cv::Mat& mask) {
  cv::Mat out;
  cv::dilate(mask, out, cv::getStructuringElement(cv::MORPH_RECT, {3, 3}));
  return out;
}

// Fraction of the mesh vertices that project (in front of the camera, inside the image) onto a
// nonzero pixel of `mask`.
double fraction_of_vertices_inside(const Mesh& mesh, const Camera& camera, const cv::Mat& mask,
                                   int* projected = nullptr) {
  int inside = 0, count = 0;
  for (const Vec3f& p : mesh.positions) {
    Eigen::Vector2d px;
    if (!camera.project(p.cast<double>(), &px) || !camera.in_image(px)) continue;
    ++count;
    if (mask.at<std::uint8_t>(static_cast<int>(px.y()), static_cast<int>(px.x()))) ++inside;
  }
  if (projected) *projected = count;
  return count ? static_cast<double>(inside) / count : 0.0;
}

TEST(Rig, CamerasOnCircleLookingAtTarget) {
  RigOptions options;
  options.count = 8;
  options.radius = 3.2;
  options.height = 1.7;
  options.target_height = 1.0;
  options.start_angle = 15;
  const std::vector<Camera> rig = make_rig(options);
  ASSERT_EQ(rig.size(), 8u);
  EXPECT_EQ(rig[0].name, "cam00");
  EXPECT_EQ(rig[7].name, "cam07");
  const Eigen::Vector3d target(0, 0, 1.0);
  for (int i = 0; i < 8; ++i) {
    const Camera& c = rig[i];
    const Eigen::Vector3d centre = c.center();
    EXPECT_NEAR(centre.head<2>().norm(), 3.2, 1e-9);
    EXPECT_NEAR(centre.z(), 1.7, 1e-9);
    const double angle = std::atan2(centre.y(), centre.x()) * 180 / std::numbers::pi;
    EXPECT_NEAR(std::remainder(angle - (15 + 45 * i), 360), 0, 1e-9) << c.name;
    EXPECT_EQ(c.intrinsics.width, 640);
    EXPECT_DOUBLE_EQ(c.intrinsics.cx, 320);
    EXPECT_DOUBLE_EQ(c.intrinsics.cy, 240);
    // The target is on the optical axis; world up is image up (negative y).
    Eigen::Vector2d px;
    ASSERT_TRUE(c.project(target, &px));
    EXPECT_NEAR(px.x(), 320, 1e-9);
    EXPECT_NEAR(px.y(), 240, 1e-9);
    ASSERT_TRUE(c.project(target + Eigen::Vector3d(0, 0, 0.3), &px));
    EXPECT_LT(px.y(), 240);
  }
}

// (a) The silhouette is exactly the set of pixels whose centre ray hits the shape.
TEST(StudioRenderer, SilhouetteMatchesAnalyticSphere) {
  const RigOptions options = test_rig();
  const Eigen::Vector3f centre(0, 0, static_cast<float>(options.target_height));
  const Mesh sphere = make_uv_sphere(centre, kRadius, 50, 100);  // 5151 vertices
  StudioRenderer renderer(quiet_studio());
  renderer.set_performer(sphere, checker_texture());
  for (const Camera& camera : make_rig(options)) {
    const RenderedView view = renderer.render(camera, 1);
    ASSERT_EQ(view.silhouette.type(), CV_8UC1);
    ASSERT_EQ(view.silhouette.size(), cv::Size(640, 480));

    // Every vertex lies inside the (1-pixel dilated) silhouette.
    int projected = 0;
    EXPECT_EQ(fraction_of_vertices_inside(sphere, camera, dilate1(view.silhouette), &projected),
              1.0)
        << camera.name;
    EXPECT_GT(projected, 2000);

    // The sphere is centred on the optical axis: its image is a disc of radius
    // f r / sqrt(d^2 - r^2).
    const double d = (camera.center() - centre.cast<double>()).norm();
    const double f = camera.intrinsics.fx;
    const double expected_area =
        std::numbers::pi * f * f * kRadius * kRadius / (d * d - kRadius * kRadius);
    const double area = cv::countNonZero(view.silhouette);
    EXPECT_NEAR(area / expected_area, 1.0, 0.02) << camera.name;

    // Pixel by pixel: the analytic sphere's coverage differs only on the one-pixel rim
    // (the mesh is inscribed, so it is a hair smaller).
    int mismatched = 0;
    for (int y = 0; y < view.silhouette.rows; ++y) {
      for (int x = 0; x < view.silhouette.cols; ++x) {
        const Ray ray = camera.unproject({x + 0.5, y + 0.5});
        const bool hit = ray_sphere(ray, centre.cast<double>(), kRadius, nullptr) > 0;
        if (hit != (view.silhouette.at<std::uint8_t>(y, x) != 0)) ++mismatched;
      }
    }
    const double perimeter = 2 * std::sqrt(std::numbers::pi * expected_area);
    EXPECT_LT(mismatched, 0.1 * perimeter) << camera.name;
  }
}

// (b) Depth is the camera z of the surface at the pixel centre.
TEST(StudioRenderer, DepthMatchesAnalyticSphere) {
  const RigOptions options = test_rig();
  const Eigen::Vector3d centre(0.3, -0.2, options.target_height);
  const Mesh sphere = make_uv_sphere(centre.cast<float>(), kRadius, 80, 160);
  StudioRenderer renderer(quiet_studio());
  renderer.set_performer(sphere, checker_texture());
  const Camera camera = make_rig(options)[1];
  const RenderedView view = renderer.render(camera, 1);
  ASSERT_EQ(view.depth.type(), CV_32FC1);
  int checked = 0;
  double worst = 0;
  for (int y = 0; y < view.depth.rows; ++y) {
    for (int x = 0; x < view.depth.cols; ++x) {
      const float depth = view.depth.at<float>(y, x);
      if (!view.silhouette.at<std::uint8_t>(y, x)) {
        EXPECT_EQ(depth, 0.0f);
        continue;
      }
      const Ray ray = camera.unproject({x + 0.5, y + 0.5});
      double cos_incidence = 0;
      const double t = ray_sphere(ray, centre, kRadius, &cos_incidence);
      // Near the rim the chord sag of the tessellation is magnified by the grazing angle.
      if (t <= 0 || cos_incidence < 0.5) continue;
      const double expected = camera.depth(ray.origin + t * ray.direction);
      worst = std::max(worst, std::abs(depth - expected));
      ++checked;
    }
  }
  EXPECT_GT(checked, 10000);
  EXPECT_LT(worst, 1e-3);
}

// (c) Same seed, same bytes, whatever the number of threads; another seed, other noise.
TEST(StudioRenderer, DeterministicNoise) {
  const RigOptions options = test_rig();
  const Mesh sphere = make_uv_sphere(
      Eigen::Vector3f(0, 0, static_cast<float>(options.target_height)), kRadius, 30, 60);
  StudioOptions studio;
  studio.noise_sigma = 3;
  StudioRenderer renderer(studio);
  renderer.set_performer(sphere, checker_texture());
  const Camera camera = make_rig(options)[0];
  const RenderedView a = renderer.render(camera, 42);
  RenderedView single;
  {
    tbb::global_control one_thread(tbb::global_control::max_allowed_parallelism, 1);
    single = renderer.render(camera, 42);
  }
  const RenderedView c = renderer.render(camera, 43);
  EXPECT_EQ(cv::norm(a.image, single.image, cv::NORM_INF), 0);
  EXPECT_EQ(cv::norm(a.silhouette, single.silhouette, cv::NORM_INF), 0);
  EXPECT_EQ(cv::norm(a.depth, single.depth, cv::NORM_INF), 0);
  EXPECT_EQ(cv::norm(a.silhouette, c.silhouette, cv::NORM_INF), 0);

  // Different noise: most pixels differ, by about sqrt(2) sigma on average.
  cv::Mat diff;
  cv::absdiff(a.image, c.image, diff);
  const double changed = cv::countNonZero(diff.reshape(1)) / static_cast<double>(diff.total() * 3);
  EXPECT_GT(changed, 0.5);
  cv::Mat da, dc;
  a.image.convertTo(da, CV_32FC3);
  c.image.convertTo(dc, CV_32FC3);
  cv::Scalar mean, stddev;
  const cv::Mat signed_diff = da - dc;
  cv::meanStdDev(signed_diff.reshape(1), mean, stddev);
  EXPECT_NEAR(mean[0], 0, 0.1);
  EXPECT_NEAR(stddev[0], std::sqrt(2.0) * 3, 0.5);

  // Without noise the seed does not matter.
  StudioOptions quiet = quiet_studio();
  StudioRenderer clean(quiet);
  clean.set_performer(sphere, checker_texture());
  EXPECT_EQ(cv::norm(clean.render(camera, 1).image, clean.render(camera, 2).image, cv::NORM_INF),
            0);
}

// (d) The renderer's lens distortion is the calibration's: Camera::project lands on the shape.
TEST(StudioRenderer, DistortionConsistentWithCameraModel) {
  RigOptions options = test_rig();
  options.k1 = -0.25;
  options.k2 = 0.08;
  options.p1 = 1.5e-3;
  options.p2 = -1e-3;
  // Off the optical axis, where the distortion moves the image by many pixels.
  const Mesh sphere = make_uv_sphere(Eigen::Vector3f(0.9, 0.9, 1.3), 0.3f, 40, 80);
  StudioRenderer renderer(quiet_studio());
  renderer.set_performer(sphere, checker_texture());
  for (const Camera& camera : make_rig(options)) {
    const RenderedView view = renderer.render(camera, 1);
    int projected = 0;
    const cv::Mat mask = dilate1(view.silhouette);
    EXPECT_EQ(fraction_of_vertices_inside(sphere, camera, mask, &projected), 1.0) << camera.name;
    if (projected == 0) continue;
    // The same check with the lens ignored fails: the test can tell the difference.
    Camera pinhole = camera;
    pinhole.intrinsics.k1 = pinhole.intrinsics.k2 = pinhole.intrinsics.p1 = pinhole.intrinsics.p2 =
        0;
    EXPECT_LT(fraction_of_vertices_inside(sphere, pinhole, mask), 0.9) << camera.name;
  }
}

// (e) The performer is not green; the screen is green-dominant; the floor is lit and the
// performer's shadow darkens it.
TEST(StudioRenderer, ColoursAndShadow) {
  RigOptions options = test_rig();
  StudioOptions studio = quiet_studio();
  studio.light_elevation = 60;
  studio.light_azimuth = 30;
  const Eigen::Vector3d centre(0, 0, 0.7);
  const Mesh sphere = make_uv_sphere(centre.cast<float>(), kRadius, 30, 60);
  StudioRenderer renderer(studio);
  renderer.set_performer(sphere, checker_texture());

  const double el = 60 * std::numbers::pi / 180, az = 30 * std::numbers::pi / 180;
  const Eigen::Vector3d light(std::cos(el) * std::cos(az), std::cos(el) * std::sin(az),
                              std::sin(el));
  const Eigen::Vector3d shadow_centre = centre - light * (centre.z() / light.z());

  int shadows_checked = 0;
  for (const Camera& camera : make_rig(options)) {
    const RenderedView view = renderer.render(camera, 1);
    ASSERT_EQ(view.image.type(), CV_8UC3);
    if (const char* dir = std::getenv("FOURD_SYNTH_DEBUG_DIR")) {  // to look at the studio
      cv::imwrite(fmt::format("{}/render_sphere_{}.png", dir, camera.name), view.image);
    }
    const cv::Scalar inside = cv::mean(view.image, view.silhouette);
    EXPECT_LT(inside[1], std::max(inside[0], inside[2])) << camera.name;  // G < max(B, R)
    // Top rows: the chroma-green screen.
    const cv::Scalar top = cv::mean(view.image(cv::Rect(0, 0, 640, 40)));
    EXPECT_GT(top[1], top[0] + 50) << camera.name;
    EXPECT_GT(top[1], top[2] + 50) << camera.name;

    // The floor under the shadow is darker than open floor far from the performer.
    Eigen::Vector2d in_shadow, open;
    // Open floor: 1.2 m from the origin towards the light, far from the shadow.
    const Eigen::Vector3d open_floor(1.2 * std::cos(az), 1.2 * std::sin(az), 0);
    if (!camera.project(shadow_centre, &in_shadow) || !camera.in_image(in_shadow)) continue;
    if (!camera.project(open_floor, &open) || !camera.in_image(open)) continue;
    auto covered = [&](const Eigen::Vector2d& p) {
      return view.silhouette.at<std::uint8_t>(static_cast<int>(p.y()), static_cast<int>(p.x())) !=
             0;
    };
    if (covered(in_shadow) || covered(open)) continue;  // hidden by the sphere from this camera
    auto grey = [&](const Eigen::Vector2d& p) {
      return cv::mean(
          view.image(cv::Rect(static_cast<int>(p.x()) - 2, static_cast<int>(p.y()) - 2, 5, 5)));
    };
    const cv::Scalar dark = grey(in_shadow), bright = grey(open);
    EXPECT_LT(dark[1], 0.6 * bright[1]) << camera.name;
    ++shadows_checked;
  }
  EXPECT_GE(shadows_checked, 1);
}

// Anti-aliasing blends colours across the performer's outline and changes nothing elsewhere.
TEST(StudioRenderer, AntiAliasingOnlyOnEdges) {
  const RigOptions options = test_rig();
  const Mesh sphere = make_uv_sphere(Eigen::Vector3f(0, 0, 1.0f), kRadius, 30, 60);
  StudioOptions aliased = quiet_studio(), smooth = quiet_studio();
  aliased.samples_per_pixel = 1;
  smooth.samples_per_pixel = 8;
  StudioRenderer a(aliased), b(smooth);
  a.set_performer(sphere, checker_texture());
  b.set_performer(sphere, checker_texture());
  const Camera camera = make_rig(options)[0];
  const RenderedView va = a.render(camera, 1), vb = b.render(camera, 1);
  EXPECT_EQ(va.stats.supersampled_pixels, 0);
  EXPECT_GT(vb.stats.supersampled_pixels, 0);
  EXPECT_EQ(cv::norm(va.silhouette, vb.silhouette, cv::NORM_INF), 0);

  // Edges: the outline (within 2 px) and the studio's own edges (the floor/screen line),
  // found by rendering the empty studio both ways.
  cv::Mat outline;
  cv::morphologyEx(va.silhouette, outline, cv::MORPH_GRADIENT,
                   cv::getStructuringElement(cv::MORPH_RECT, {5, 5}));
  auto changed_pixels = [](const cv::Mat& p, const cv::Mat& q) {
    cv::Mat diff, gray;
    cv::absdiff(p, q, diff);
    cv::cvtColor(diff, gray, cv::COLOR_BGR2GRAY);
    return cv::Mat(gray > 0);
  };
  StudioRenderer empty_a(aliased), empty_b(smooth);
  const cv::Mat studio_edges =
      changed_pixels(empty_a.render(camera, 1).image, empty_b.render(camera, 1).image);
  const cv::Mat changed = changed_pixels(va.image, vb.image);
  int changed_on_outline = 0, changed_elsewhere = 0;
  for (int y = 0; y < changed.rows; ++y) {
    for (int x = 0; x < changed.cols; ++x) {
      if (!changed.at<std::uint8_t>(y, x)) continue;
      if (outline.at<std::uint8_t>(y, x)) {
        ++changed_on_outline;
      } else if (!studio_edges.at<std::uint8_t>(y, x)) {
        ++changed_elsewhere;
      }
    }
  }
  const int outline_pixels = cv::countNonZero(va.silhouette) > 0 ? cv::countNonZero(outline) : 0;
  EXPECT_GT(changed_on_outline, outline_pixels / 4);
  EXPECT_EQ(changed_elsewhere, 0);
}

TEST(StudioRenderer, EmptyStudioHasNoSilhouette) {
  StudioRenderer renderer(StudioOptions{});
  const RenderedView view = renderer.render(make_rig(test_rig())[0], 7);
  EXPECT_EQ(cv::countNonZero(view.silhouette), 0);
  EXPECT_EQ(cv::countNonZero(view.depth), 0);
}

TEST(StudioRenderer, RejectsBadPerformer) {
  StudioRenderer renderer(StudioOptions{});
  Mesh sphere = make_uv_sphere(Eigen::Vector3f(0, 0, 1), 0.5f, 8, 16);
  EXPECT_THROW(renderer.set_performer(sphere, cv::Mat()), InputError);
  EXPECT_THROW(renderer.set_performer(sphere, cv::Mat(8, 8, CV_8UC1, cv::Scalar(0))), InputError);
  sphere.uvs.pop_back();
  EXPECT_THROW(renderer.set_performer(sphere, checker_texture()), InputError);
}

}  // namespace
}  // namespace fourd::synth
