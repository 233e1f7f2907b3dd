#include "stages/reconstruct/fusion.h"

#include <gtest/gtest.h>

namespace fourd::reconstruct {
namespace {

// A camera at the origin looking along +z, 64 x 64 pixels, 90 degrees wide.
PinholeCamera looking_up_z() {
  PinholeCamera cam;
  cam.name = "cam";
  cam.width = cam.height = 64;
  cam.K << 32, 0, 32, 0, 32, 32, 0, 0, 1;
  return cam;
}

// Samples every 5 cm over [-0.2, 0.2] x [-0.2, 0.2] x [0.7, 1.5], all just inside the "hull"
// (within the fused band), so that only the depth maps decide.
ScalarGrid hull_block() {
  ScalarGrid grid;
  grid.origin = Eigen::Vector3d(-0.2, -0.2, 0.7);
  grid.voxel = 0.05;
  grid.nx = grid.ny = 9;
  grid.nz = 17;
  grid.values.assign(static_cast<std::size_t>(grid.nx) * grid.ny * grid.nz, -0.01f);
  return grid;
}

// The camera measured a wall at depth 1 everywhere, with a perfect score.
DepthMap wall_at_depth_one() {
  DepthMap map;
  map.depth = cv::Mat(64, 64, CV_32F, cv::Scalar(1.0f));
  map.score = cv::Mat(64, 64, CV_32F, cv::Scalar(1.0f));
  return map;
}

int z_index(const ScalarGrid& grid, double z) {
  return static_cast<int>(std::lround((z - grid.origin.z()) / grid.voxel));
}

TEST(Fusion, DepthVotesAreRecordedInFrontOfTheMeasuredSurfaceAndNotFarBehindIt) {
  ScalarGrid field = hull_block();
  ScalarGrid weight;
  FusionOptions options;  // truncation 15 mm
  fuse_depth_maps(field, {looking_up_z()}, {wall_at_depth_one()}, 0.7, options, &weight);
  ASSERT_EQ(weight.values.size(), field.values.size());
  // In front of the wall: one full vote; carved (the field turns positive, outside).
  EXPECT_FLOAT_EQ(weight.at(4, 4, z_index(weight, 0.9)), 1.0f);
  EXPECT_GT(field.at(4, 4, z_index(field, 0.9)), 0.0f);
  // Far behind it (hidden from the camera): no vote, and the hull's value stays.
  EXPECT_FLOAT_EQ(weight.at(4, 4, z_index(weight, 1.3)), 0.0f);
  EXPECT_FLOAT_EQ(field.at(4, 4, z_index(field, 1.3)), -0.01f);
}

TEST(Fusion, SurfaceConfidenceIsTheDepthsShareOfTheVote) {
  ScalarGrid field = hull_block();
  ScalarGrid weight;
  FusionOptions options;
  options.hull_weight = 0.25;
  fuse_depth_maps(field, {looking_up_z()}, {wall_at_depth_one()}, 0.7, options, &weight);
  Mesh mesh;
  mesh.positions = {Vec3f(0.01f, 0.01f, 1.0f),    // on the measured wall
                    Vec3f(0.01f, 0.01f, 1.32f),   // behind it: only the hull says so
                    Vec3f(3.0f, 0.0f, 1.0f)};     // outside the grid
  const std::vector<float> confidence = surface_confidence(mesh, weight, options);
  ASSERT_EQ(confidence.size(), 3u);
  EXPECT_NEAR(confidence[0], 1.0 / 1.25, 1e-6);
  EXPECT_FLOAT_EQ(confidence[1], 0.0f);
  EXPECT_FLOAT_EQ(confidence[2], 0.0f);
}

}  // namespace
}  // namespace fourd::reconstruct
