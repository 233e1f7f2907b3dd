#include "stages/reconstruct/subject.h"

#include <gtest/gtest.h>

#include <cmath>

#include "stages/reconstruct/plausibility.h"

namespace fourd::reconstruct {
namespace {

// `count` cameras on a circle of `radius` at `height`, looking at (0, 0, target); the studio's
// image size and focal length.
std::vector<Camera> ring(int count, double radius, double height, double target) {
  std::vector<Camera> cams;
  for (int i = 0; i < count; ++i) {
    const double a = 2 * M_PI * i / count;
    Camera c;
    c.name = "cam" + std::to_string(i);
    c.intrinsics = {320, 240, 280, 280, 160, 120};
    c.camera_from_world = look_at({radius * std::cos(a), radius * std::sin(a), height},
                                  {0, 0, target}, {0, 0, 1});
    cams.push_back(c);
  }
  return cams;
}

// Pixels whose centre ray passes through the box `lo`..`hi` (an upright box stands in for a
// standing subject).
cv::Mat box_silhouette(const Camera& cam, const Eigen::Vector3d& lo, const Eigen::Vector3d& hi) {
  cv::Mat s(cam.intrinsics.height, cam.intrinsics.width, CV_8U, cv::Scalar(0));
  for (int y = 0; y < s.rows; ++y) {
    for (int x = 0; x < s.cols; ++x) {
      const Ray r = cam.unproject({x + 0.5, y + 0.5});
      double t0 = 0, t1 = 1e9;
      for (int a = 0; a < 3; ++a) {
        const double inv = 1 / r.direction[a];
        double ta = (lo[a] - r.origin[a]) * inv, tb = (hi[a] - r.origin[a]) * inv;
        if (ta > tb) std::swap(ta, tb);
        t0 = std::max(t0, ta);
        t1 = std::min(t1, tb);
      }
      if (t0 <= t1) s.at<std::uint8_t>(y, x) = 255;
    }
  }
  return s;
}

SubjectScale measure(double s, const SubjectScaleOptions& options = {}) {
  const std::vector<Camera> cams = ring(8, 3.5 * s, 1.6 * s, 0.9 * s);
  const VisualHullOptions hull;
  const Box shared = shared_volume(cams, required_views(hull, 8));
  const Eigen::Vector3d lo(-0.2 * s, -0.15 * s, 0), hi(0.2 * s, 0.15 * s, 1.75 * s);
  std::vector<cv::Mat> sils;
  for (const Camera& c : cams) sils.push_back(box_silhouette(c, lo, hi));
  return measure_subject({cams}, {sils}, hull, shared, options);
}

TEST(SubjectScale, SharedVolumeAndFactorScaleWithTheRig) {
  const std::vector<Camera> big = ring(8, 3.5, 1.6, 0.9), small = ring(8, 0.175, 0.08, 0.045);
  const Box a = shared_volume(big, 6), b = shared_volume(small, 6);
  ASSERT_FALSE(a.empty());
  // The studio's cameras share a volume around the middle of the ring, inside it.
  EXPECT_LT(a.min.x(), -1.0);
  EXPECT_GT(a.max.x(), 1.0);
  EXPECT_LT(a.max.x(), 3.5);
  EXPECT_GT(a.max.z(), 2.0);
  for (int k = 0; k < 3; ++k) {
    EXPECT_NEAR(b.min[k] * 20, a.min[k], 1e-6);
    EXPECT_NEAR(b.max[k] * 20, a.max[k], 1e-6);
  }
  const SubjectScale reference = measure(1), tiny = measure(0.05);
  ASSERT_TRUE(reference.measured);
  // A 1.75 m box is measured within a few cm (its hull from 8 views) and gets factor 1 exactly.
  EXPECT_NEAR(reference.size, 1.75, 0.08);
  EXPECT_NEAR(reference.height, 1.75, 0.08);
  EXPECT_EQ(reference.factor, 1.0);
  EXPECT_NEAR(tiny.size * 20, reference.size, 1e-6);
  EXPECT_NEAR(tiny.factor, 0.05, 0.003);  // 10^(-26/20), the R20 step nearest to 0.05
  SubjectScaleOptions exact;
  exact.steps_per_decade = 0;
  EXPECT_NEAR(measure(0.05, exact).factor * 20, measure(1, exact).factor, 1e-6);
}

TEST(SubjectScale, GivenSizeAndRounding) {
  SubjectScaleOptions given;
  given.subject_size = 0.35;
  const SubjectScale s = measure(1, given);
  EXPECT_FALSE(s.measured);
  EXPECT_DOUBLE_EQ(s.factor, 0.2);
  EXPECT_EQ(subject_scale_factor(1.75 * 1.05, 20), 1.0);
  EXPECT_NEAR(subject_scale_factor(1.75 * 2, 20), std::pow(10.0, 6 / 20.0), 1e-12);
  EXPECT_DOUBLE_EQ(subject_scale_factor(3.5, 0), 2.0);
}

TEST(SubjectScale, NoHullIsAnError) {
  const std::vector<Camera> cams = ring(8, 3.5, 1.6, 0.9);
  const VisualHullOptions hull;
  const Box shared = shared_volume(cams, required_views(hull, 8));
  const std::vector<cv::Mat> empty(8, cv::Mat(240, 320, CV_8U, cv::Scalar(0)));
  EXPECT_THROW(measure_subject({cams}, {empty}, hull, shared, {}), InputError);
}

TEST(SubjectScale, DerivedVolumeKeepsTheReferenceAndScales) {
  const VisualHullOptions reference;
  const Box shared = shared_volume(ring(8, 3.5, 1.6, 0.9), 6);
  VisualHullOptions h;
  derive_volume(h, shared, 1.0);
  // On the studio rig the shared volume lies in the default one in x, y and below: those stay.
  for (int a = 0; a < 2; ++a) EXPECT_EQ(h.volume_min[a], reference.volume_min[a]);
  EXPECT_EQ(h.volume_min[2], reference.volume_min[2]);
  EXPECT_GE(h.volume_max[2], reference.volume_max[2]);
  VisualHullOptions t;
  derive_volume(t, shared_volume(ring(8, 0.175, 0.08, 0.045), 6), 0.05);
  for (int a = 0; a < 3; ++a) {
    EXPECT_NEAR(t.volume_min[a] * 20, h.volume_min[a], 1e-6);
    EXPECT_NEAR(t.volume_max[a] * 20, h.volume_max[a], 1e-6);
  }
}

// A hull from silhouettes that disagree (one camera sees the subject elsewhere) is flagged, and
// a mesh far smaller than the hull is too; consistent silhouettes and the hull itself are not.
TEST(Plausibility, FlagsInconsistentSilhouettesAndASmallMesh) {
  const std::vector<Camera> cams = ring(8, 3.5, 1.6, 0.9);
  const Eigen::Vector3d lo(-0.2, -0.15, 0), hi(0.2, 0.15, 1.75);
  std::vector<cv::Mat> sils;
  for (const Camera& c : cams) sils.push_back(box_silhouette(c, lo, hi));
  VisualHullOptions h;
  h.voxel_size = 0.02;
  h.volume_min = {-1, -1, -0.05};
  h.volume_max = {1, 1, 2.2};
  const Mesh hull = VisualHull(cams, sils, h).mesh();
  ASSERT_FALSE(hull.triangles.empty());
  const PlausibilityOptions options;
  const PlausibilityReport ok = check_plausibility(cams, sils, hull, hull, h.voxel_size, options);
  EXPECT_TRUE(ok.warnings.empty()) << ok.warnings.front();
  ASSERT_EQ(ok.hull.size(), 8u);
  for (const OutlineOverlap& o : ok.hull) EXPECT_GT(o.coverage, 0.9);
  EXPECT_NEAR(ok.volume_ratio, 1.0, 1e-9);

  // Camera 2 (looking along -y) sees the subject 0.25 m off to one side: the other cameras
  // carve away most of what it sees.
  std::vector<cv::Mat> bad = sils;
  const Eigen::Vector3d off(0.25, 0, 0);
  bad[2] = box_silhouette(cams[2], lo + off, hi + off);
  const Mesh bad_hull = VisualHull(cams, bad, h).mesh();
  const PlausibilityReport flagged =
      check_plausibility(cams, bad, bad_hull, bad_hull, h.voxel_size, options);
  ASSERT_FALSE(flagged.warnings.empty());
  bool names_camera = false;
  for (const std::string& w : flagged.warnings) names_camera |= w.find("camera cam2:") == 0;
  EXPECT_TRUE(names_camera) << flagged.warnings.front();

  // A mesh a fifth of the hull's size, in its middle.
  Mesh small = hull;
  const Vec3f c(0, 0, 0.9f);
  for (Vec3f& p : small.positions) p = c + 0.2f * (p - c);
  const PlausibilityReport shrunk = check_plausibility(cams, sils, hull, small, h.voxel_size, options);
  bool too_small = false, uncovered = false;
  for (const std::string& w : shrunk.warnings) {
    too_small |= w.find("far smaller than the visual hull") != std::string::npos;
    uncovered |= w.find("the mesh covers only") != std::string::npos;
  }
  EXPECT_TRUE(too_small);
  EXPECT_TRUE(uncovered);
  EXPECT_LT(shrunk.volume_ratio, 0.01);

  // Voxels far too coarse for the subject.
  const PlausibilityReport coarse = check_plausibility(cams, sils, hull, hull, 0.1, options);
  ASSERT_EQ(coarse.warnings.size(), 1u);
  EXPECT_NE(coarse.warnings[0].find("voxel size is too coarse"), std::string::npos);
}

}  // namespace
}  // namespace fourd::reconstruct
