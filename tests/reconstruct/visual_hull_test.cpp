#include "stages/reconstruct/visual_hull.h"

#include <gtest/gtest.h>

#include <cmath>

namespace fourd::reconstruct {
namespace {

// Eight cameras on a circle looking at the origin, like the studio rig.
std::vector<Camera> ring_cameras(int count, double radius, double height) {
  std::vector<Camera> cams;
  for (int i = 0; i < count; ++i) {
    double a = 2 * M_PI * i / count;
    Camera c;
    c.name = "cam" + std::to_string(i);
    c.intrinsics = {320, 240, 300, 300, 160, 120};
    c.camera_from_world = look_at({radius * std::cos(a), radius * std::sin(a), height},
                                  {0, 0, height}, {0, 0, 1});
    cams.push_back(c);
  }
  return cams;
}

// Exact silhouette of a sphere: pixels whose centre ray hits it.
cv::Mat sphere_silhouette(const Camera& cam, const Eigen::Vector3d& c, double r) {
  cv::Mat s(cam.intrinsics.height, cam.intrinsics.width, CV_8U, cv::Scalar(0));
  for (int y = 0; y < s.rows; ++y)
    for (int x = 0; x < s.cols; ++x) {
      Ray ray = cam.unproject({x + 0.5, y + 0.5});
      Eigen::Vector3d oc = ray.origin - c;
      double b = oc.dot(ray.direction), disc = b * b - (oc.squaredNorm() - r * r);
      if (disc >= 0) s.at<std::uint8_t>(y, x) = 255;
    }
  return s;
}

TEST(VisualHull, SignedDistanceIsZeroHalfWayAcrossTheBoundary) {
  cv::Mat s(10, 10, CV_8U, cv::Scalar(0));
  s(cv::Rect(0, 0, 5, 10)).setTo(255);
  cv::Mat d = silhouette_signed_distance(s);
  EXPECT_FLOAT_EQ(d.at<float>(3, 4), -0.5f);
  EXPECT_FLOAT_EQ(d.at<float>(3, 5), 0.5f);
  EXPECT_FLOAT_EQ(d.at<float>(3, 0), -4.5f);
}

TEST(VisualHull, SphereHullContainsTheSphereWithinTheOctagonBound) {
  const Eigen::Vector3d centre(0.1, -0.05, 0.9);
  const double r = 0.3;
  std::vector<Camera> cams = ring_cameras(8, 3.0, 0.9);
  std::vector<cv::Mat> sils;
  for (const Camera& c : cams) sils.push_back(sphere_silhouette(c, centre, r));
  VisualHullOptions opts;
  opts.voxel_size = 0.01;
  opts.volume_min = {-1, -1, 0};
  opts.volume_max = {1, 1, 2};
  VisualHull hull(cams, sils, opts);
  EXPECT_LT(hull.value(centre), -0.25);
  EXPECT_GT(hull.value(centre + Eigen::Vector3d(0.5, 0, 0)), 0.1);
  Mesh m = hull.mesh();
  ASSERT_GT(m.positions.size(), 100u);
  // The hull of a sphere from 8 cameras on its equator is at most an octagon around it
  // (r / cos 22.5 deg) there, and never cuts into it — up to the silhouette's half-pixel
  // quantisation (a pixel is 1 cm at 3 m) and one grid edge of the isosurface (a cell
  // diagonal, sqrt(3) voxels, for marching tetrahedra).
  const double tolerance = 0.5 * 3.0 / 300.0 + std::sqrt(3.0) * opts.voxel_size;
  for (const Vec3f& p : m.positions) {
    Eigen::Vector3d d = p.cast<double>() - centre;
    ASSERT_GT(d.norm(), r - tolerance) << "hull cuts into the sphere at " << d.transpose();
    if (std::abs(d.z()) < 0.05) {
      EXPECT_LT(d.norm(), r / std::cos(M_PI / 8) + tolerance);
    }
  }
}

TEST(VisualHull, EmptySilhouettesGiveNoMesh) {
  std::vector<Camera> cams = ring_cameras(4, 3.0, 0.9);
  std::vector<cv::Mat> sils(4, cv::Mat(240, 320, CV_8U, cv::Scalar(0)));
  VisualHullOptions opts;
  VisualHull hull(cams, sils, opts);
  EXPECT_TRUE(hull.mesh().triangles.empty());
}

}  // namespace
}  // namespace fourd::reconstruct
