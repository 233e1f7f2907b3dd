// Similarity matrices of the motion graph and the lower bound of Eq. 3 (stages/graph/similarity.h,
// runtime/motion_graph.h).
#include "stages/graph/similarity.h"

#include <gtest/gtest.h>

#include <random>

#include "pipeline/core/error.h"
#include "pipeline/core/se2.h"
#include "tests/graph/test_graph.h"

namespace fourd {
namespace {

std::array<float, 3> random_weights(std::mt19937& rng, int n) {
  std::uniform_real_distribution<float> u(0.f, 1.f);
  std::array<float, 3> w{};
  float sum = 0;
  for (int i = 0; i < n; ++i) sum += (w[i] = u(rng));
  for (int i = 0; i < n; ++i) w[i] /= sum;
  return w;
}

TEST(GraphSimilarity, MatrixHasItsSizesAndRange) {
  const MotionGraph g = test::make_test_graph(true);
  for (const GraphEdge& e : g.edges) {
    const EdgeSimilarity& s = e.similarity;
    EXPECT_EQ(s.source_inputs, g.spaces[e.from].num_inputs());
    EXPECT_EQ(s.target_samples, g.spaces[e.to].num_samples());
    float lo = 1, hi = 0;
    for (float v : s.values) {
      lo = std::min(lo, v);
      hi = std::max(hi, v);
    }
    EXPECT_GE(lo, 0.f);
    EXPECT_LE(hi, 1.f);
    EXPECT_NEAR(lo, 0.f, 1e-6f);  // the farthest pair defines d_max
  }
}

TEST(GraphSimilarity, SelfLoopDiagonalIsOneAndCycleCloses) {
  const MotionGraph g = test::make_test_graph();
  const int loop = g.find_edge(0, 0);
  ASSERT_GE(loop, 0);
  const EdgeSimilarity& s = g.edges[loop].similarity;
  for (int u = 0; u < s.source_samples; ++u) {
    for (int i = 0; i < s.source_inputs; ++i) EXPECT_NEAR(s.at(u, u, i, i), 1.f, 1e-5f);
  }
  // The last sample closes the cycle: same shape and velocity as sample 0.
  const int last = s.source_samples - 1;
  for (int i = 0; i < s.source_inputs; ++i) EXPECT_NEAR(s.at(last, 0, i, i), 1.f, 1e-4f);
  // A jump is not a loop.
  EXPECT_LT(g.find_edge(1, 1), 0);
}

TEST(GraphSimilarity, VelocityFeatureSeesRootMotion) {
  // Two inputs with identical shapes but different forward speeds differ only by velocity.
  test::SpaceRecipe r = test::walk_recipe();
  r.amplitude = {30, 30};
  r.hybrid_reference = false;
  const MotionSpace s = test::make_test_space(r);
  SimilarityDefinition def;
  def.frame_time = 0.04;
  def.velocity_weight = 1.0;
  const Eigen::MatrixXf a = graph::input_features(s, 0, def);
  const Eigen::MatrixXf b = graph::input_features(s, 1, def);
  const int nv = s.blend.num_vertices;
  // Shapes differ only by the constant 3-degree offset per input index; velocities differ by
  // the root speed: (1.28 / 0.8 - 1.0 / 1.0) m/s x 0.04 s along x for every vertex.
  const Eigen::Index u = 5;
  const double vx_a = a.col(u).segment(3 * nv, nv).mean();
  const double vx_b = b.col(u).segment(3 * nv, nv).mean();
  EXPECT_NEAR(vx_b - vx_a, (1.28 / 0.8 - 1.0) * 0.04, 2e-3);
}

// Eq. 3: the weighted sum of input similarities never exceeds the similarity of the blends
// (linear blends of positions and velocities, interpolated between samples), on sampled states.
TEST(GraphSimilarity, LowerBoundNeverExceedsTrueSimilarity) {
  const MotionGraph g = test::make_test_graph(true);
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> ut(0.0, 1.0);
  int checked = 0;
  double tightest = 1;
  for (const GraphEdge& e : g.edges) {
    const MotionSpace& a = g.spaces[e.from].motion;
    const MotionSpace& b = g.spaces[e.to].motion;
    std::vector<Eigen::MatrixXf> fa, fb;
    for (int i = 0; i < a.num_inputs(); ++i) fa.push_back(graph::input_features(a, i, g.similarity));
    for (int j = 0; j < b.num_inputs(); ++j) fb.push_back(graph::input_features(b, j, g.similarity));
    for (int k = 0; k < 300; ++k) {
      const double ts = ut(rng), tt = ut(rng);
      const std::array<float, 3> ws = random_weights(rng, a.num_inputs());
      const std::array<float, 3> wt = random_weights(rng, b.num_inputs());
      const double lb = similarity_lower_bound(e.similarity, ts, ws, tt, wt);
      const double d = graph::feature_distance(graph::linear_state_features(fa, ts, ws),
                                               graph::linear_state_features(fb, tt, wt));
      const double truth = 1 - d / e.similarity.max_distance;
      EXPECT_LE(lb, truth + 1e-5) << "edge " << e.from << "->" << e.to << " ts " << ts << " tt "
                                  << tt;
      tightest = std::min(tightest, truth - lb);
      ++checked;
    }
  }
  EXPECT_GT(checked, 1000);
  EXPECT_LT(tightest, 0.05);  // the bound is not vacuous
}

// At input weights and sample times the bound is the matrix entry itself, i.e. exact.
TEST(GraphSimilarity, LowerBoundIsExactAtInputsAndSamples) {
  const MotionGraph g = test::make_test_graph();
  const GraphEdge& e = g.edges[0];
  const MotionSpace& a = g.spaces[e.from].motion;
  const MotionSpace& b = g.spaces[e.to].motion;
  const Eigen::MatrixXf fa = graph::input_features(a, 1, g.similarity);
  const Eigen::MatrixXf fb = graph::input_features(b, 0, g.similarity);
  const int u = 4, v = 7;
  const double ts = static_cast<double>(u) / (a.num_samples() - 1);
  const double tt = static_cast<double>(v) / (b.num_samples() - 1);
  const std::array<float, 3> ws{0, 1, 0}, wt{1, 0, 0};
  const double d = graph::feature_distance(fa.col(u), fb.col(v));
  EXPECT_NEAR(similarity_lower_bound(e.similarity, ts, ws, tt, wt),
              1 - d / e.similarity.max_distance, 1e-5);
}

TEST(GraphSimilarity, NormalsAreUnitAndPointOutwards) {
  const MotionSpace s = test::make_test_space(test::walk_recipe());
  AlignedFloats n;
  AlignedHalfs nd;
  graph::reference_normals(s, &n, &nd);
  ASSERT_EQ(n.size(), s.blend.frames.size());
  ASSERT_EQ(nd.size(), s.blend.displacements.size());
  // A reference's normals are stored like its positions: the linear blend of the inputs'
  // normals plus an fp16 displacement, which gives back unit normals.
  ASSERT_GT(s.blend.num_references(), s.blend.num_inputs);
  BlendSpace normals = s.blend;
  normals.frames = n;
  normals.displacements = nd;
  std::vector<float> r(normals.frame_stride());
  reference_frame(normals, normals.num_inputs, 1, r.data());
  for (int v = 0; v < normals.num_vertices; ++v) {
    const int ps = normals.plane_stride;
    EXPECT_NEAR(Eigen::Vector3f(r[v], r[ps + v], r[2 * ps + v]).norm(), 1.f, 1e-3f);
  }
  const float* x = s.blend.frames.data();
  const int stride = s.blend.plane_stride, nv = s.blend.num_vertices;
  // Tube centre line is near x = y = 0 at frame 0 of input 0 for the lower rings: the normal
  // of a side vertex points away from the axis.
  int outward = 0;
  for (int v = 0; v < nv; ++v) {
    const Eigen::Vector3f nn(n[v], n[stride + v], n[2 * stride + v]);
    EXPECT_NEAR(nn.norm(), 1.f, 1e-4f);
    if (x[2 * stride + v] < 0.2f && (x[v] * nn.x() + x[stride + v] * nn.y()) > 0) ++outward;
  }
  EXPECT_GT(outward, 8);
}

TEST(GraphSimilarity, BuildRejectsUnknownTransition) {
  std::vector<MotionSpace> spaces{test::make_test_space(test::walk_recipe())};
  const std::vector<TransitionConfig> transitions{{"locomotion", "swim"}};
  EXPECT_THROW(graph::build_motion_graph("t", 25, spaces, transitions, {}, nullptr), InputError);
}

TEST(GraphSimilarity, ShortestRouteGoesThroughTheGraph) {
  const MotionGraph g = test::make_test_graph(true);
  const int jump = g.find_space("jump_length"), turn = g.find_space("turning");
  // jump -> turning has no edge: via locomotion.
  EXPECT_LT(g.find_edge(jump, turn), 0);
  const std::vector<int> route = shortest_route(g, jump, turn);
  ASSERT_EQ(route.size(), 2u);
  EXPECT_EQ(route[0], g.find_space("locomotion"));
  EXPECT_EQ(route[1], turn);
  EXPECT_TRUE(shortest_route(g, jump, jump).empty());
}

}  // namespace
}  // namespace fourd
