#include "stages/reconstruct/depth_map.h"
#include "stages/reconstruct/depth_fill.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>

#include <opencv2/imgproc.hpp>

#include "pipeline/core/camera.h"
#include "stages/validate/sampling.h"

namespace fourd::reconstruct {
namespace {

constexpr double kRadius = 0.5;  // the textured sphere, centred at the origin

// Cameras 30 degrees apart on a circle of radius 2.5 m, all looking at the origin.
std::vector<PinholeCamera> arc_cameras(int count) {
  std::vector<PinholeCamera> cams;
  for (int i = 0; i < count; ++i) {
    const double a = (i - (count - 1) / 2.0) * M_PI / 6;
    Camera c;
    c.name = "cam" + std::to_string(i);
    c.intrinsics = {640, 480, 600, 600, 320, 240};
    c.camera_from_world = look_at({2.5 * std::cos(a), 2.5 * std::sin(a), 0}, {0, 0, 0}, {0, 0, 1});
    cams.push_back(PinholeCamera::from(c));
  }
  return cams;
}

// Depth along the optical axis of the first hit of a centred sphere of radius r (0: miss).
double sphere_depth(const PinholeCamera& cam, double x, double y, double r) {
  const Eigen::Vector3d o = cam.center();
  const Eigen::Vector3d d = (cam.unproject(x, y, 1.0) - o).normalized();
  const double b = o.dot(d), disc = b * b - (o.squaredNorm() - r * r);
  if (disc < 0) return 0;
  return cam.to_camera(o + (-b - std::sqrt(disc)) * d).z();
}

// Grey level of the sphere's surface: a sum of plane waves of 2-4 cm wavelength, as clothing
// detail is at the studio's resolution.
float texture(const Eigen::Vector3d& p) {
  static const double waves[6][4] = {{0.8, 0.5, 0.3, 170},  {-0.3, 0.9, 0.3, 230},
                                     {0.2, -0.4, 0.9, 200}, {0.6, 0.6, -0.5, 280},
                                     {-0.7, 0.1, 0.7, 150}, {0.1, 0.7, 0.7, 310}};
  double v = 128;
  for (const auto& w : waves) v += 18 * std::sin(w[3] * (w[0] * p.x() + w[1] * p.y() + w[2] * p.z()));
  return static_cast<float>(v);
}

// The view of a textured sphere, with a hull `hull_margin` larger than the sphere.
StereoView sphere_view(const PinholeCamera& cam, double hull_margin) {
  StereoView v;
  v.camera = cam;
  v.gray = cv::Mat(cam.height, cam.width, CV_32F, cv::Scalar(20));
  v.hull_depth = cv::Mat::zeros(cam.height, cam.width, CV_32F);
  for (int y = 0; y < cam.height; ++y) {
    for (int x = 0; x < cam.width; ++x) {
      const double d = sphere_depth(cam, x + 0.5, y + 0.5, kRadius);
      if (d > 0) v.gray.at<float>(y, x) = texture(cam.unproject(x + 0.5, y + 0.5, d));
      v.hull_depth.at<float>(y, x) =
          static_cast<float>(sphere_depth(cam, x + 0.5, y + 0.5, kRadius + hull_margin));
    }
  }
  v.roi = cv::boundingRect(v.hull_depth > 0);
  return v;
}

// The exact depth map of the sphere in `cam` (score 1 everywhere it is seen).
DepthMap exact_depth_map(const PinholeCamera& cam) {
  DepthMap m;
  m.depth = cv::Mat::zeros(cam.height, cam.width, CV_32F);
  m.score = cv::Mat(cam.height, cam.width, CV_32F, cv::Scalar(-1));
  for (int y = 0; y < cam.height; ++y) {
    for (int x = 0; x < cam.width; ++x) {
      const double d = sphere_depth(cam, x + 0.5, y + 0.5, kRadius);
      if (d <= 0) continue;
      m.depth.at<float>(y, x) = static_cast<float>(d);
      m.score.at<float>(y, x) = 1;
    }
  }
  return m;
}

// The hull's first hit per pixel: a sphere `margin` larger than the textured one.
cv::Mat hull_depth_of(const PinholeCamera& cam, double margin) {
  cv::Mat hull = cv::Mat::zeros(cam.height, cam.width, CV_32F);
  for (int y = 0; y < cam.height; ++y) {
    for (int x = 0; x < cam.width; ++x) {
      hull.at<float>(y, x) = static_cast<float>(sphere_depth(cam, x + 0.5, y + 0.5, kRadius + margin));
    }
  }
  return hull;
}

// Largest error of the depths of `map` in `rect` against the sphere's.
double worst_depth_error(const PinholeCamera& cam, const DepthMap& map, const cv::Rect& rect) {
  double worst = 0;
  for (int y = rect.y; y < rect.y + rect.height; ++y) {
    for (int x = rect.x; x < rect.x + rect.width; ++x) {
      worst = std::max(worst, std::abs(map.depth.at<float>(y, x) -
                                       sphere_depth(cam, x + 0.5, y + 0.5, kRadius)));
    }
  }
  return worst;
}

TEST(DepthFill, APatchWithoutDepthIsFilledOnTheSphere) {
  const PinholeCamera cam = arc_cameras(3)[1];
  DepthMap map = exact_depth_map(cam);
  // A 13 cm patch of the sphere's front (40 x 40 px) that matching left empty, and a few lone
  // pixels elsewhere.
  const cv::Rect patch(300, 220, 40, 40);
  map.depth(patch).setTo(0);
  map.score(patch).setTo(-1);
  const std::vector<cv::Point> lone = {{250, 200}, {380, 300}, {330, 150}};
  for (const cv::Point& p : lone) map.depth.at<float>(p) = 0;

  const std::size_t filled = fill_depth_holes(hull_depth_of(cam, 0.03), map, 0.01, 0.1, {});
  EXPECT_EQ(filled, static_cast<std::size_t>(patch.area()) + lone.size());
  EXPECT_EQ(cv::countNonZero(map.filled(patch)), patch.area());
  // The depth behind the 3 cm larger hull varies slowly over the patch: interpolated from its
  // border, it is within a millimetre of the sphere's (the hull alone is 3 cm off).
  EXPECT_LT(worst_depth_error(cam, map, patch), 0.001);
  for (const cv::Point& p : lone) {
    EXPECT_NEAR(map.depth.at<float>(p), sphere_depth(cam, p.x + 0.5, p.y + 0.5, kRadius), 0.0002);
  }
}

TEST(DepthFill, WrongMatchesOnTheBorderDoNotSpreadAndOpenHolesStayEmpty) {
  const PinholeCamera cam = arc_cameras(3)[1];
  const cv::Mat hull = hull_depth_of(cam, 0.03);
  DepthMap map = exact_depth_map(cam);
  // The band between the sphere and its 3 cm larger hull has no depth and borders the outline
  // for about half its length: it is not enclosed, whatever its size.
  const cv::Mat band = (hull > 0) & (map.depth <= 0);
  ASSERT_GT(cv::countNonZero(band), 500);
  // A hole with a few wrong matches (5 cm too far) along its top border.
  const cv::Rect patch(300, 220, 40, 40);
  map.depth(patch).setTo(0);
  map.depth(cv::Rect(310, 219, 6, 1)) += 0.05f;
  map.depth(cv::Rect(325, 218, 3, 2)) += 0.05f;
  DepthFillOptions options;
  options.max_pixels = 1000000;
  EXPECT_EQ(fill_depth_holes(hull, map, 0.01, 0.1, options), static_cast<std::size_t>(patch.area()));
  EXPECT_EQ(cv::countNonZero(map.filled & band), 0);
  EXPECT_LT(worst_depth_error(cam, map, patch), 0.001);
}

TEST(DepthMap, TexturedSphereIsMatchedToSubPixelPrecision) {
  const std::vector<PinholeCamera> cams = arc_cameras(3);
  std::vector<StereoView> views;
  for (const PinholeCamera& c : cams) views.push_back(sphere_view(c, 0.03));
  const DepthMap map = estimate_depth_map(views, 1, {0, 2}, DepthMapOptions{});

  // Error of every depth as the distance, in the neighbour's image, between where the estimated
  // and the true point project: the disparity error the sweep makes.
  std::vector<double> pixel_error, depth_error;
  int sphere_pixels = 0, off_sphere = 0;
  for (int y = 0; y < cams[1].height; ++y) {
    for (int x = 0; x < cams[1].width; ++x) {
      const double truth = sphere_depth(cams[1], x + 0.5, y + 0.5, kRadius);
      if (truth > 0) ++sphere_pixels;
      const float d = map.depth.at<float>(y, x);
      if (d <= 0) continue;
      if (truth <= 0) {  // the hull's margin around the sphere, matched by its window
        ++off_sphere;
        continue;
      }
      const Eigen::Vector3d p = cams[1].unproject(x + 0.5, y + 0.5, d);
      const Eigen::Vector3d q = cams[1].unproject(x + 0.5, y + 0.5, truth);
      pixel_error.push_back((cams[0].pixel(cams[0].to_camera(p)) -
                             cams[0].pixel(cams[0].to_camera(q))).norm());
      depth_error.push_back(std::abs(d - truth));
    }
  }
  // Most of the sphere gets a depth (not its grazing rim), to a fraction of a pixel, and
  // hardly any pixel off it.
  EXPECT_LT(off_sphere, 0.02 * pixel_error.size());
  EXPECT_GT(pixel_error.size(), 0.85 * sphere_pixels);
  EXPECT_LT(percentile(pixel_error, 0.5), 0.1);
  EXPECT_LT(percentile(pixel_error, 0.9), 0.4);
  EXPECT_LT(percentile(depth_error, 0.5), 0.001);
}

TEST(DepthMap, BestNeighbourScoreMatchesWhatOnlyOneNeighbourSees) {
  const std::vector<PinholeCamera> cams = arc_cameras(3);
  std::vector<StereoView> views;
  for (const PinholeCamera& c : cams) views.push_back(sphere_view(c, 0.03));
  // Something the hull does not know of hides the middle of the sphere from camera 2: its image
  // shows another texture there.
  const cv::Rect hidden(280, 200, 80, 80);
  cv::Mat occluder = views[2].gray(hidden);
  cv::randu(occluder, 0, 255);
  cv::GaussianBlur(occluder, occluder, cv::Size(), 1.0);
  // The reference pixels whose sphere point camera 2 sees behind the occluder.
  auto behind_occluder = [&](int x, int y) {
    const double d = sphere_depth(cams[1], x + 0.5, y + 0.5, kRadius);
    if (d <= 0) return false;
    const Eigen::Vector2d px = cams[2].pixel(cams[2].to_camera(cams[1].unproject(x + 0.5, y + 0.5, d)));
    return hidden.contains(cv::Point(static_cast<int>(px.x()) - 4, static_cast<int>(px.y()) - 4)) &&
           hidden.contains(cv::Point(static_cast<int>(px.x()) + 4, static_cast<int>(px.y()) + 4));
  };
  auto coverage = [&](const std::string& score) {
    DepthMapOptions options;
    options.neighbour_score = score;
    const DepthMap map = estimate_depth_map(views, 1, {0, 2}, options);
    int pixels = 0, matched = 0;
    for (int y = 0; y < cams[1].height; ++y) {
      for (int x = 0; x < cams[1].width; ++x) {
        if (!behind_occluder(x, y)) continue;
        ++pixels;
        const float d = map.depth.at<float>(y, x);
        const double truth = sphere_depth(cams[1], x + 0.5, y + 0.5, kRadius);
        if (d > 0 && std::abs(d - truth) < 0.003) ++matched;
      }
    }
    EXPECT_GT(pixels, 2000);
    return double(matched) / std::max(pixels, 1);
  };
  // The mean of a good and a meaningless score falls below min_ncc; the best one does not.
  EXPECT_LT(coverage("mean"), 0.3);
  EXPECT_GT(coverage("best"), 0.7);
}

TEST(DepthMap, ConsistencyCheckRemovesADepthNoOtherMapConfirms) {
  const std::vector<PinholeCamera> cams = arc_cameras(3);
  std::vector<DepthMap> maps;
  for (const PinholeCamera& c : cams) maps.push_back(exact_depth_map(c));
  // A patch of wrong depths (5 cm too far) in the middle camera, at the sphere's centre.
  const cv::Rect wrong(300, 220, 40, 40);
  cv::Mat patch = maps[1].depth(wrong);
  patch += 0.05f;
  const int before = cv::countNonZero(maps[1].depth > 0);

  const std::size_t removed = keep_consistent_depths(cams, maps, 1, 0.01);
  EXPECT_GT(removed, 0u);
  EXPECT_EQ(cv::countNonZero(maps[1].depth(wrong) > 0), 0);
  EXPECT_EQ(cv::countNonZero(maps[1].score(wrong) >= 0), 0);
  // The right depths around it stay: the whole front of the sphere is seen by a neighbour.
  const cv::Rect front(240, 160, 160, 160);
  cv::Mat kept = maps[1].depth(front) > 0;
  EXPECT_EQ(cv::countNonZero(kept), front.area() - wrong.area());
  EXPECT_LT(cv::countNonZero(maps[1].depth > 0), before);
}

}  // namespace
}  // namespace fourd::reconstruct
