#include "runtime/viewer/view_math.h"

#include <gtest/gtest.h>

#include <cmath>
#include <vector>

namespace fourd::viewer {
namespace {

// Pixel of a world point (x right, y down), as the GPU would draw it.
Eigen::Vector2f project(const OrbitCamera& camera, const Eigen::Vector3f& p, int w, int h) {
  const Eigen::Vector4f clip =
      camera.projection(static_cast<float>(w) / h) * camera.view() * Eigen::Vector4f(p.x(), p.y(), p.z(), 1);
  const Eigen::Vector2f ndc = clip.head<2>() / clip.w();
  return {(ndc.x() + 1) * 0.5f * w, (1 - ndc.y()) * 0.5f * h};
}

TEST(ViewerMath, PickingAPixelFindsTheGroundPointDrawnThere) {
  OrbitCamera camera;
  camera.mode = CameraMode::kOrbit;
  camera.target = {2, -1, 0.9f};
  camera.yaw = 0.7f;
  camera.pitch = 0.5f;
  camera.distance = 6;
  const int w = 1280, h = 720;
  for (const Eigen::Vector3f& g : {Eigen::Vector3f(2, -1, 0), Eigen::Vector3f(4.5f, 0.3f, 0),
                                   Eigen::Vector3f(1, -2.5f, 0)}) {
    const Eigen::Vector2f pixel = project(camera, g, w, h);
    Point2 picked;
    ASSERT_TRUE(pick_ground(camera.view(), camera.projection(static_cast<float>(w) / h), pixel.x(),
                            pixel.y(), w, h, &picked));
    EXPECT_NEAR(picked.x, g.x(), 1e-3);
    EXPECT_NEAR(picked.y, g.y(), 1e-3);
  }
  // Looking down at 0.1 rad with a vertical field of view of 0.8 rad, the top of the image is
  // sky: no ground there, but ground at the bottom.
  camera.pitch = 0.1f;
  const Mat4f projection = camera.projection(static_cast<float>(w) / h);
  Point2 ground;
  EXPECT_FALSE(pick_ground(camera.view(), projection, 640, 0, w, h, &ground));
  EXPECT_TRUE(pick_ground(camera.view(), projection, 640, h - 1, w, h, &ground));
}

TEST(ViewerMath, OrbitCameraLooksAtItsTargetFromItsDistance) {
  OrbitCamera camera;
  camera.mode = CameraMode::kOrbit;
  camera.yaw = 0;
  camera.pitch = 0;
  camera.distance = 3;
  camera.target = {1, 2, 1};
  // yaw 0: behind the target along -x, looking along +x.
  EXPECT_TRUE(camera.eye().isApprox(Eigen::Vector3f(-2, 2, 1)));
  const Eigen::Vector4f t = camera.view() * Eigen::Vector4f(1, 2, 1, 1);
  EXPECT_NEAR(t.x(), 0, 1e-5);
  EXPECT_NEAR(t.y(), 0, 1e-5);
  EXPECT_NEAR(t.z(), -3, 1e-5);  // in front of the camera (OpenGL looks down -z)
  camera.zoom(1);
  EXPECT_LT(camera.distance, 3);
}

TEST(ViewerMath, FollowCameraSwingsBehindTheCharacterWhateverTheFrameRate) {
  OrbitCamera a, b;
  a.follow(3, 4, 1.0, 0.5);
  for (int k = 0; k < 10; ++k) b.follow(3, 4, 1.0, 0.05);
  EXPECT_NEAR(a.follow_heading, b.follow_heading, 1e-5);
  EXPECT_GT(a.follow_heading, 0.5);
  EXPECT_LT(a.follow_heading, 1.0);
  EXPECT_FLOAT_EQ(a.target.x(), 3);
  EXPECT_FLOAT_EQ(a.target.y(), 4);
  for (int k = 0; k < 100; ++k) a.follow(3, 4, 1.0, 0.1);
  EXPECT_NEAR(a.follow_heading, 1.0, 1e-4);
}

TEST(ViewerMath, ClickedPointsMakeASmoothPathTheControllerAccepts) {
  const std::vector<Point2> points{{0, 0}, {2, 0}, {2, 0.001}, {4, 2}, {4, 5}};
  const std::vector<BezierCurve> curves = bezier_through(points);
  ASSERT_EQ(curves.size(), 3u);  // the point 1 mm from its neighbour is dropped
  EXPECT_DOUBLE_EQ(curves.front().control[0].x, 0);
  EXPECT_DOUBLE_EQ(curves.back().control[3].y, 5);
  for (std::size_t i = 0; i + 1 < curves.size(); ++i) {
    const BezierCurve& a = curves[i];
    const BezierCurve& b = curves[i + 1];
    // Contiguous, and the same tangent on both sides of each joint (C1).
    EXPECT_DOUBLE_EQ(a.control[3].x, b.control[0].x);
    EXPECT_DOUBLE_EQ(a.control[3].y, b.control[0].y);
    EXPECT_NEAR(a.control[3].x - a.control[2].x, b.control[1].x - b.control[0].x, 1e-12);
    EXPECT_NEAR(a.control[3].y - a.control[2].y, b.control[1].y - b.control[0].y, 1e-12);
  }
  const GroundPath path(curves);
  EXPECT_GT(path.length(), 2 + 2 * std::sqrt(2.0) + 3 - 1e-6);  // at least the chords
  const Point2 mid = bezier_point(curves[1], 0.5);
  EXPECT_NEAR(path.point_at(path.closest(mid, 0, path.length())).x, mid.x, 0.01);
  EXPECT_TRUE(bezier_through(std::vector<Point2>{{1, 1}}).empty());
  EXPECT_TRUE(bezier_through(std::vector<Point2>{{1, 1}, {1, 1.001}}).empty());
}

}  // namespace
}  // namespace fourd::viewer
