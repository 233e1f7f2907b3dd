#include "stages/align/diagnosis.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <set>

#include "pipeline/geometry/remesh.h"
#include "stages/align/align.h"
#include "tests/align/align_test_data.h"

namespace fourd::align {
namespace {

struct Fixture {
  Mesh templ = remesh_to_vertex_count(test::make_figure().rest, 2000);
  RegistrationOptions options;
  TemplateModel model = build_template_model(templ, options);
  TemplateRegions regions = make_regions(model, 24);
  DiagnosisLimits limits = diagnosis_limits(1.75);
};

const Fixture& fixture() {
  static const Fixture f;
  return f;
}

// The region holding the lowest vertex (a foot of the figure).
int lowest_region(const Fixture& f) {
  const auto& p = f.templ.positions;
  const auto it = std::min_element(p.begin(), p.end(), [](const Vec3f& a, const Vec3f& b) { return a.z() < b.z(); });
  return f.regions.of_vertex[it - p.begin()];
}

TEST(Diagnosis, PatchesCoverTheTemplateAndAreNamed) {
  const Fixture& f = fixture();
  ASSERT_EQ(f.regions.names.size(), 24u);
  std::vector<int> size(24, 0);
  for (int r : f.regions.of_vertex) {
    ASSERT_GE(r, 0);
    ASSERT_LT(r, 24);
    ++size[r];
  }
  // Farthest-point patches are of comparable size: none empty, none a third of the template.
  for (int s : size) {
    EXPECT_GT(s, 0);
    EXPECT_LT(s, static_cast<int>(f.templ.num_vertices()) / 3);
  }
  EXPECT_NE(f.regions.names[0].find("% up"), std::string::npos);
}

TEST(Diagnosis, ARightFitIsNotFlagged) {
  const Fixture& f = fixture();
  const SurfaceQuery target(f.templ);
  const auto cues = region_cues(f.model, f.regions, f.templ.positions, target, f.options.coverage_distance);
  EXPECT_TRUE(judge(cues, f.limits).empty());
  EXPECT_LT(badness(cues, f.limits), 0.2);
}

TEST(Diagnosis, APatchOffTheSurfaceIsFlaggedAndNamed) {
  const Fixture& f = fixture();
  const int foot = lowest_region(f);
  // The fit left one patch 8 cm off the frame (a foot that did not follow).
  std::vector<Vec3f> positions = f.templ.positions;
  for (std::size_t i = 0; i < positions.size(); ++i) {
    if (f.regions.of_vertex[i] == foot) positions[i] += Vec3f(0.08f, 0, 0);
  }
  const SurfaceQuery target(f.templ);
  const auto cues = region_cues(f.model, f.regions, positions, target, f.options.coverage_distance);
  const auto verdicts = judge(cues, f.limits);
  ASSERT_FALSE(verdicts.empty());
  std::set<int> named;
  for (const RegionVerdict& v : verdicts) named.insert(v.region);
  EXPECT_TRUE(named.count(foot));
  // The residual cue names the moved patch first.
  EXPECT_EQ(verdicts.front().region, foot);
}

TEST(Diagnosis, AFrameUncoveredWhereTheTemplateLeftIsFlagged) {
  const Fixture& f = fixture();
  // The frame has a limb the fit did not follow: the template's foot was pulled up onto the
  // leg, so the frame's foot is far from any fitted surface.
  const int foot = lowest_region(f);
  std::vector<Vec3f> positions = f.templ.positions;
  for (std::size_t i = 0; i < positions.size(); ++i) {
    if (f.regions.of_vertex[i] == foot) positions[i].z() += 0.12f;
  }
  const SurfaceQuery target(f.templ);
  const auto cues = region_cues(f.model, f.regions, positions, target, f.options.coverage_distance);
  EXPECT_FALSE(judge(cues, f.limits).empty());
}

TEST(Diagnosis, APatchThatSlidInOneFrameJumps) {
  const Fixture& f = fixture();
  const int foot = lowest_region(f);
  std::vector<Vec3f> before = f.templ.positions, after = f.templ.positions, now = f.templ.positions;
  for (auto& p : before) p.x() -= 0.02f;  // the figure walks 2 cm per frame
  for (auto& p : after) p.x() += 0.02f;
  for (std::size_t i = 0; i < now.size(); ++i) {
    if (f.regions.of_vertex[i] == foot) now[i].y() += 0.06f;  // slid sideways in this frame only
  }
  const std::vector<double> jumps = region_jumps(f.regions, now, before, after);
  ASSERT_EQ(jumps.size(), f.regions.names.size());
  for (std::size_t r = 0; r < jumps.size(); ++r) {
    if (static_cast<int>(r) == foot) {
      EXPECT_NEAR(jumps[r], 0.06, 1e-4);
    } else {
      EXPECT_NEAR(jumps[r], 0.0, 1e-4);
    }
  }
  std::vector<RegionCues> cues(jumps.size());
  for (std::size_t r = 0; r < jumps.size(); ++r) {
    cues[r].jump = jumps[r];
    cues[r].jump_ratio = jumps[r] / 0.005;  // the take's typical jump: 5 mm
  }
  const auto verdicts = judge(cues, f.limits);
  ASSERT_EQ(verdicts.size(), 1u);
  EXPECT_EQ(verdicts[0].region, foot);
  EXPECT_EQ(verdicts[0].cue, "jump");
}

// A foot fitted to the other leg jumps far beyond what the motion between two frames explains,
// and is registered again; a hand that moves fast is only flagged.
TEST(Diagnosis, AFootOnTheOtherLegJumpsFarAFastHandDoesNot) {
  const Fixture& f = fixture();
  const int foot = lowest_region(f);
  const double centre_y = [&] {
    double lo = 1e9, hi = -1e9;
    for (const Vec3f& p : f.templ.positions) lo = std::min<double>(lo, p.y()), hi = std::max<double>(hi, p.y());
    return 0.5 * (lo + hi);
  }();
  std::vector<Vec3f> swapped = f.templ.positions, fast = f.templ.positions;
  for (std::size_t i = 0; i < swapped.size(); ++i) {
    if (f.regions.of_vertex[i] != foot) continue;
    swapped[i].y() = static_cast<float>(2 * centre_y) - swapped[i].y();  // on the other leg
    fast[i].x() += 0.1f;                                                // 10 cm ahead
  }
  const auto cues_of = [&](const std::vector<Vec3f>& now) {
    const std::vector<double> jumps = region_jumps(f.regions, now, f.templ.positions, f.templ.positions);
    std::vector<RegionCues> cues(jumps.size());
    for (std::size_t r = 0; r < jumps.size(); ++r) {
      cues[r].jump = jumps[r];
      cues[r].jump_ratio = jumps[r] / 0.01;  // the take's typical jump: 1 cm
    }
    return cues;
  };
  const double factor = AlignOptions{}.retry_jump_factor;
  const auto far = cues_of(swapped);
  ASSERT_GT(far[foot].jump, factor * f.limits.jump) << "the figure's feet are too close to test";
  EXPECT_TRUE(jumps_far(far, f.limits, factor));
  const auto quick = cues_of(fast);
  EXPECT_FALSE(judge(quick, f.limits).empty());  // flagged,
  EXPECT_FALSE(jumps_far(quick, f.limits, factor));  // not registered again
  EXPECT_FALSE(jumps_far(cues_of(f.templ.positions), f.limits, factor));
}

}  // namespace
}  // namespace fourd::align
