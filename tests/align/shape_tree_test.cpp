#include "stages/align/shape_tree.h"

#include <gtest/gtest.h>

#include "pipeline/core/error.h"
#include "pipeline/geometry/measures.h"
#include "stages/align/shape_descriptor.h"
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

}  // namespace
}  // namespace fourd::align
