#include "pipeline/core/camera.h"

#include <gtest/gtest.h>

#include <opencv2/calib3d.hpp>
#include <opencv2/core/eigen.hpp>

#include "pipeline/core/error.h"

namespace fourd {
namespace {

// A 640x480 camera with strong-but-real lens distortion, 3 m from the origin, looking at it.
Camera test_camera(bool distortion = true) {
  Camera c;
  c.name = "cam00";
  c.intrinsics.width = 640;
  c.intrinsics.height = 480;
  c.intrinsics.fx = 600;
  c.intrinsics.fy = 590;
  c.intrinsics.cx = 321.5;
  c.intrinsics.cy = 238.25;
  if (distortion) {
    c.intrinsics.k1 = -0.21;
    c.intrinsics.k2 = 0.05;
    c.intrinsics.p1 = 1.2e-3;
    c.intrinsics.p2 = -7e-4;
  }
  c.camera_from_world = look_at({3, 0.5, 1.6}, {0, 0, 0.9}, {0, 0, 1});
  return c;
}

TEST(Camera, LookAtAxes) {
  const Eigen::Vector3d eye(3, 0.5, 1.6), target(0, 0, 0.9);
  const Camera c = test_camera();
  // Rotation is orthonormal and proper.
  const Eigen::Matrix3d r = c.camera_from_world.linear();
  EXPECT_LT((r * r.transpose() - Eigen::Matrix3d::Identity()).norm(), 1e-12);
  EXPECT_NEAR(r.determinant(), 1.0, 1e-12);
  // The centre is the eye, the target lies on the optical axis in front.
  EXPECT_LT((c.center() - eye).norm(), 1e-12);
  const Eigen::Vector3d t_cam = c.camera_from_world * target;
  EXPECT_NEAR(t_cam.x(), 0, 1e-12);
  EXPECT_NEAR(t_cam.y(), 0, 1e-12);
  EXPECT_NEAR(t_cam.z(), (target - eye).norm(), 1e-12);
  EXPECT_NEAR(c.depth(target), (target - eye).norm(), 1e-12);
  // World up maps to image up (camera -y), world "right of the view" to image +x.
  const Eigen::Vector3d above = c.camera_from_world * Eigen::Vector3d(target + Eigen::Vector3d(0, 0, 0.1));
  EXPECT_LT(above.y(), 0);
  // Looking along -x from +x with z up, the world +y direction is to the right of the image.
  const Eigen::Vector3d right = c.camera_from_world * Eigen::Vector3d(target + Eigen::Vector3d(0, 0.1, 0));
  EXPECT_GT(right.x(), 0);
}

TEST(Camera, LookAtRejectsDegenerateInput) {
  EXPECT_THROW(look_at({1, 1, 1}, {1, 1, 1}, {0, 0, 1}), InputError);
  EXPECT_THROW(look_at({0, 0, 2}, {0, 0, 0}, {0, 0, 1}), InputError);  // up along the view
}

TEST(Camera, TargetProjectsToPrincipalPoint) {
  const Camera c = test_camera();
  Eigen::Vector2d px;
  ASSERT_TRUE(c.project({0, 0, 0.9}, &px));
  EXPECT_NEAR(px.x(), c.intrinsics.cx, 1e-9);
  EXPECT_NEAR(px.y(), c.intrinsics.cy, 1e-9);
}

TEST(Camera, PointBehindCameraDoesNotProject) {
  const Camera c = test_camera();
  const Eigen::Vector3d eye = c.center();
  const Eigen::Vector3d behind = eye + (eye - Eigen::Vector3d(0, 0, 0.9));
  Eigen::Vector2d px(-7, -7);
  EXPECT_FALSE(c.project(behind, &px));
  EXPECT_EQ(px, Eigen::Vector2d(-7, -7));  // untouched
  EXPECT_LT(c.depth(behind), 0);
  EXPECT_FALSE(c.project(eye, &px));  // the centre itself has depth 0
}

TEST(Camera, DistortUndistortRoundTripOverImage) {
  const Camera c = test_camera();
  double worst = 0;
  for (int row = 0; row <= 480; row += 8) {
    for (int col = 0; col <= 640; col += 8) {
      // Distorted normalised coordinates of the pixel, as in unproject().
      const Eigen::Vector2d d((col - c.intrinsics.cx) / c.intrinsics.fx,
                              (row - c.intrinsics.cy) / c.intrinsics.fy);
      const Eigen::Vector2d u = c.undistort(d);
      worst = std::max(worst, (c.distort(u) - d).norm());
    }
  }
  EXPECT_LT(worst, 1e-12);
  // The distortion is not the identity, so undistort really did something.
  const Eigen::Vector2d corner(-0.5, -0.4);
  EXPECT_GT((c.undistort(corner) - corner).norm(), 1e-2);
}

TEST(Camera, ProjectUnprojectRoundTripOverImage) {
  const Camera c = test_camera();
  double worst_px = 0, worst_dir = 0;
  for (int row = 0; row <= 480; row += 16) {
    for (int col = 0; col <= 640; col += 16) {
      const Eigen::Vector2d px(col + 0.5, row + 0.5);
      const Ray ray = c.unproject(px);
      EXPECT_NEAR(ray.direction.norm(), 1.0, 1e-12);
      EXPECT_LT((ray.origin - c.center()).norm(), 1e-12);
      for (double dist : {0.5, 2.5, 10.0}) {
        const Eigen::Vector3d point = ray.origin + dist * ray.direction;
        Eigen::Vector2d back;
        ASSERT_TRUE(c.project(point, &back));
        worst_px = std::max(worst_px, (back - px).norm());
      }
      // And the other way: a world point's pixel unprojects to the ray through the point.
      const Eigen::Vector3d point = ray.origin + 3.0 * ray.direction;
      Eigen::Vector2d p2;
      ASSERT_TRUE(c.project(point, &p2));
      const Ray r2 = c.unproject(p2);
      worst_dir = std::max(worst_dir, (r2.direction - (point - c.center()).normalized()).norm());
    }
  }
  EXPECT_LT(worst_px, 1e-8);
  EXPECT_LT(worst_dir, 1e-12);
}

// Our distortion and pixel convention agree with OpenCV's projectPoints once the principal
// point is shifted by half a pixel (opencv_camera_matrix()).
TEST(Camera, MatchesOpenCvProjectPoints) {
  const Camera c = test_camera();
  std::vector<cv::Point3d> world;
  for (double x : {-0.4, 0.0, 0.3}) {
    for (double y : {-0.5, 0.2}) {
      for (double z : {0.1, 0.9, 1.8}) world.emplace_back(x, y, z);
    }
  }
  cv::Mat rmat, rvec, tvec, k, dist;
  cv::eigen2cv(Eigen::Matrix3d(c.camera_from_world.linear()), rmat);
  cv::Rodrigues(rmat, rvec);
  cv::eigen2cv(Eigen::Vector3d(c.camera_from_world.translation()), tvec);
  cv::eigen2cv(c.intrinsics.opencv_camera_matrix(), k);
  cv::eigen2cv(c.intrinsics.opencv_distortion(), dist);
  std::vector<cv::Point2d> expected;
  cv::projectPoints(world, rvec, tvec, k, dist, expected);
  for (size_t i = 0; i < world.size(); ++i) {
    Eigen::Vector2d px;
    ASSERT_TRUE(c.project({world[i].x, world[i].y, world[i].z}, &px));
    EXPECT_NEAR(px.x(), expected[i].x + 0.5, 1e-7) << i;
    EXPECT_NEAR(px.y(), expected[i].y + 0.5, 1e-7) << i;
  }
}

TEST(Camera, NoDistortionIsPinhole) {
  const Camera c = test_camera(false);
  const Eigen::Vector2d d(0.3, -0.2);
  EXPECT_EQ(c.distort(d), d);
  EXPECT_EQ(c.undistort(d), d);
  // The four image corners unproject to rays through the corners of the pinhole frustum.
  const Ray ray = c.unproject({0, 0});
  const Eigen::Vector3d cam_dir = c.camera_from_world.linear() * ray.direction;
  EXPECT_NEAR(cam_dir.x() / cam_dir.z(), -c.intrinsics.cx / c.intrinsics.fx, 1e-12);
  EXPECT_NEAR(cam_dir.y() / cam_dir.z(), -c.intrinsics.cy / c.intrinsics.fy, 1e-12);
}

TEST(Camera, InImageUsesPixelEdges) {
  const Camera c = test_camera();
  EXPECT_TRUE(c.in_image({0, 0}));
  EXPECT_TRUE(c.in_image({639.99, 479.99}));
  EXPECT_FALSE(c.in_image({640, 10}));
  EXPECT_FALSE(c.in_image({10, -0.01}));
}

}  // namespace
}  // namespace fourd
