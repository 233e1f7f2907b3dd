#include "stages/align/shape_tree.h"

#include <gtest/gtest.h>

#include "pipeline/core/error.h"
#include "pipeline/geometry/measures.h"
#include "stages/align/mesh_tools.h"
#include "stages/align/shape_descriptor.h"
#include "stages/align/surface_query.h"
#include "tests/align/align_test_data.h"
#include "tests/test_shapes.h"

namespace fourd::align {
namespace {

// Frames on a line at `at`: their distances are the differences.
Eigen::MatrixXd line_distances(const std::vector<double>& at) {
  const int n = static_cast<int>(at.size());
  Eigen::MatrixXd distance(n, n);
  for (int i = 0; i < n; ++i) {
    for (int j = 0; j < n; ++j) distance(i, j) = std::abs(at[i] - at[j]);
  }
  return distance;
}

TEST(ShapeTree, TwoClearlyDifferentPosesFormTwoBranches) {
  // Three frames of a walk near one phase and three of the arms raised sideways, given in
  // alternating order: the tree must join each group within itself and cross between the
  // groups once.
  const test::Figure figure = test::make_figure(0.02);
  std::vector<Mesh> frames;
  std::vector<int> group;
  for (int k = 0; k < 3; ++k) {
    frames.push_back(test::pose_figure(figure, test::walk_pose(figure, 0.1 * k, 0.3 * k)));
    group.push_back(0);
    frames.push_back(test::pose_figure(figure, test::arms_raised_pose(figure, 80 + 5 * k)));
    group.push_back(1);
  }
  const DescriptorOptions options;
  std::vector<ShapeDescriptor> descriptors;
  for (const Mesh& m : frames) descriptors.push_back(compute_shape_descriptor(m, options));
  const ShapeTree tree = minimum_spanning_tree(pairwise_shape_distances(descriptors, options).value);

  int crossings = 0;
  for (std::size_t k = 0; k < frames.size(); ++k) {
    if (tree.parent[k] >= 0 && group[tree.parent[k]] != group[k]) ++crossings;
  }
  EXPECT_EQ(crossings, 1);
}

TEST(ShapeTree, RootIsTheMostCentralFrameUnlessOneIsForced) {
  // Five frames on a line at 0, 1, 2, 3, 4: the tree is the chain and its medoid is frame 2.
  const Eigen::MatrixXd distance = line_distances({0, 1, 2, 3, 4});
  const ShapeTree tree = minimum_spanning_tree(distance);
  EXPECT_EQ(tree.root, 2);
  EXPECT_EQ(tree.parent, (std::vector<int>{1, 2, -1, 2, 3}));
  EXPECT_EQ(tree.depth, (std::vector<int>{2, 1, 0, 1, 2}));
  const ShapeTree forced = minimum_spanning_tree(distance, 4);
  EXPECT_EQ(forced.root, 4);
  EXPECT_EQ(forced.parent, (std::vector<int>{1, 2, 3, 4, -1}));
  EXPECT_EQ(forced.order, (std::vector<int>{4, 3, 2, 1, 0}));
}

TEST(ShapeTree, CentralFrameIsTheMedoidOrANearOneWithFewerHandles) {
  // Frames on a line at 0, 1, 2, 2.1, 4: distance sums 9.1, 6.1, 5.1, 5.2, 10.9.
  const Eigen::MatrixXd distance = line_distances({0, 1, 2, 2.1, 4});
  EXPECT_EQ(central_frame(distance), 2);
  // Frame 3's sum is within 2 % of frame 2's: with fewer handles it is the root.
  EXPECT_EQ(central_frame(distance, {0, 0, 3, 1, 0}, 0.02), 3);
  // ... but not with a tolerance of 1 %, nor with as many handles.
  EXPECT_EQ(central_frame(distance, {0, 0, 3, 1, 0}, 0.01), 2);
  EXPECT_EQ(central_frame(distance, {0, 0, 1, 1, 0}, 0.02), 2);
  // Frames 0 and 1 have no handles but are far from central.
  EXPECT_EQ(central_frame(distance, {0, 0, 3, 3, 0}, 0.02), 2);
  EXPECT_THROW(central_frame(distance, {0, 0}, 0.02), InputError);
}

TEST(MeshTools, SmallHandlesAreRemovedAndLargeOnesKept) {
  // A ball with a thin loop (a tube of 8 mm radius) attached to it at two places: one handle.
  auto ball_with_loop = [](const Eigen::Vector3d& p) {
    const double ball = p.norm() - 0.2;
    const Eigen::Vector3d q = p - Eigen::Vector3d(0.21, 0, 0);
    const double loop = std::hypot(std::hypot(q.x(), q.z()) - 0.04, q.y()) - 0.008;
    return std::min(ball, loop);
  };
  const Mesh mesh = test::isosurface_of(ball_with_loop, {-0.25, -0.25, -0.25}, {0.3, 0.25, 0.25}, 0.005);
  ASSERT_EQ(check_manifold(mesh).handles, 1);
  const Mesh cleaned = remove_small_handles(mesh, 0.005, 3);
  EXPECT_EQ(check_manifold(cleaned).handles, 0);
  EXPECT_EQ(check_manifold(cleaned).components, 1);
  // The ball itself is the input's surface, to within a fraction of the voxel.
  const SurfaceQuery input(mesh);
  int far = 0;
  for (const Vec3f& p : cleaned.positions) far += input.closest(p, 1.0f).distance > 0.002f;
  EXPECT_LT(far, static_cast<int>(cleaned.num_vertices() / 50));
  // Closed and opened by one voxel at most, only a handle a few voxels thin goes: the 16 mm
  // tube goes at 5 mm voxels (three across) and stays at 2 mm (eight).
  EXPECT_EQ(check_manifold(remove_small_handles(mesh, 0.002, 1)).handles, 1);
  EXPECT_EQ(check_manifold(remove_small_handles(mesh, 0.005, 1)).handles, 0);

  // A torus's hole is far wider than the clean-up: the torus is returned as it is.
  auto torus = [](const Eigen::Vector3d& p) {
    return std::hypot(std::hypot(p.x(), p.y()) - 0.3, p.z()) - 0.1;
  };
  const Mesh ring = test::isosurface_of(torus, {-0.5, -0.5, -0.2}, {0.5, 0.5, 0.2}, 0.02);
  const Mesh kept = remove_small_handles(ring, 0.005, 3);
  EXPECT_EQ(kept.positions, ring.positions);
  EXPECT_EQ(check_manifold(kept).handles, 1);
}

}  // namespace
}  // namespace fourd::align
