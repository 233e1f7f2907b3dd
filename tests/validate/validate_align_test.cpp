// Oracle inputs (fresh re-meshing) and the align validator's measurements on hand-made data.
#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <filesystem>

#include "pipeline/core/files.h"
#include "pipeline/core/mesh_io.h"
#include "stages/validate/validate_align.h"
#include "tests/test_shapes.h"

namespace fourd::validate {
namespace {

namespace fs = std::filesystem;

class AlignMeasure : public ::testing::Test {
 protected:
  void SetUp() override {
    root_ = fs::temp_directory_path() / ("fourd_validate_align_" + std::to_string(::getpid()));
    fs::remove_all(root_);
    truth0_ = test::make_icosphere(3, 0.3f);
    truth1_ = truth0_;
    for (Vec3f& p : truth1_.positions) p += Vec3f(0.1f, 0, 0);
    write_ply(root_ / "truth" / "t" / "000000.ply", truth0_);
    write_ply(root_ / "truth" / "t" / "000001.ply", truth1_);
    write_ply(root_ / "align" / "template.ply", truth0_);
    write_file_atomic(root_ / "align" / "tree.json",
                      R"({"root": 0, "nodes": [{"take": "t", "frame": 0}, {"take": "t", "frame": 1}]})");
  }
  void TearDown() override { fs::remove_all(root_); }
  AlignmentErrors measure() {
    AlignmentErrors e = measure_alignment(root_ / "align", root_ / "truth", root_ / "truth", true);
    e.summarise();
    return e;
  }
  fs::path root_;
  Mesh truth0_, truth1_;
};

TEST_F(AlignMeasure, ExactAlignmentHasNoError) {
  write_ply(root_ / "align" / "t" / "000000.ply", truth0_);
  write_ply(root_ / "align" / "t" / "000001.ply", truth1_);
  const AlignmentErrors e = measure();
  ASSERT_EQ(e.frames.size(), 2u);
  EXPECT_LT(e.correspondence_rms, 1e-5);
  EXPECT_LT(e.surface_rms, 1e-5);
  EXPECT_EQ(e.flipped, 0);
}

TEST_F(AlignMeasure, FrameLeftBehindAndFlippedTrianglesAreMeasured) {
  write_ply(root_ / "align" / "t" / "000000.ply", truth0_);
  write_ply(root_ / "align" / "t" / "000001.ply", truth0_);  // not moved: 0.1 m off
  AlignmentErrors e = measure();
  EXPECT_NEAR(e.correspondence_rms, 0.1 / std::sqrt(2.0), 1e-4);
  EXPECT_NEAR(e.frames[1].correspondence[0], 0.1, 1e-5);
  EXPECT_GT(e.surface_rms, 0.0);
  EXPECT_EQ(e.flipped, 0);

  // A fold: one vertex pushed through the surface to the other side of the centre turns its
  // (5 or 6) incident triangles over, and nothing else.
  Mesh folded = truth1_;
  const Vec3f centre(0.1f, 0, 0);
  folded.positions[0] = centre - 0.5f * (folded.positions[0] - centre);
  write_ply(root_ / "align" / "t" / "000001.ply", folded);
  e = measure();
  int incident = 0;
  for (const Tri& t : truth0_.triangles) incident += t[0] == 0 || t[1] == 0 || t[2] == 0;
  EXPECT_EQ(e.flipped, incident);
  EXPECT_EQ(e.flipped_distinct, incident);
  // Every flipped triangle has the pushed vertex, 1.5 x its distance from the centre off.
  const float pushed = 1.5f * (truth1_.positions[0] - centre).norm();
  EXPECT_NEAR(e.flipped_error_median, pushed, 1e-5);
}

// Two balls touch at the root frame and part in the next; the template is the first ball, its
// vertex at the contact pushed 4 mm out (as a reconstruction bridges a contact), so that its
// closest truth point is on the other ball. It is bound to its own ball, as its neighbours are:
// a perfect alignment of the first ball measures 4 mm there, not the 0.3 m the other ball moved.
TEST_F(AlignMeasure, AVertexAtAContactIsBoundToItsNeighboursPart) {
  const Mesh ball = test::make_icosphere(3, 0.1f);
  // The template's vertex facing +x, and the other ball 5 mm beyond it at the root.
  int contact = 0;
  for (std::size_t i = 0; i < ball.num_vertices(); ++i) {
    if (ball.positions[i].x() > ball.positions[contact].x()) contact = static_cast<int>(i);
  }
  const auto two_balls = [&](float gap_x) {
    Mesh both = ball;
    const int offset = static_cast<int>(ball.num_vertices());
    for (const Vec3f& p : ball.positions) both.positions.push_back(p + Vec3f(0.2f + gap_x, 0, 0));
    for (const Tri& t : ball.triangles) both.triangles.push_back({t[0] + offset, t[1] + offset, t[2] + offset});
    return both;
  };
  Mesh templ = ball;
  templ.positions[contact] += Vec3f(0.004f, 0, 0);
  const Mesh truth0 = two_balls(0.005f), truth1 = two_balls(0.3f);
  write_ply(root_ / "truth" / "t" / "000000.ply", truth0);
  write_ply(root_ / "truth" / "t" / "000001.ply", truth1);
  write_ply(root_ / "align" / "template.ply", templ);
  write_ply(root_ / "align" / "t" / "000000.ply", templ);
  write_ply(root_ / "align" / "t" / "000001.ply", templ);  // the first ball does not move
  const AlignmentErrors e = measure();
  EXPECT_EQ(e.rebound, 1);
  ASSERT_EQ(e.frames.size(), 2u);
  for (const AlignedFrameError& f : e.frames) {
    EXPECT_NEAR(f.correspondence[contact], 0.004, 1e-4) << "frame " << f.frame;
  }
}

}  // namespace
}  // namespace fourd::validate
