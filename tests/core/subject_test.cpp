// The session's subject: reconstruct's record read back, measured on meshes when there is
// none, and the factor's rounding that keeps subjects near the reference on the tuned defaults.
#include "pipeline/core/subject.h"

#include <gtest/gtest.h>

#include <cmath>
#include <fstream>

#include "pipeline/core/error.h"
#include "tests/scratch_dir.h"
#include "tests/test_shapes.h"

namespace fourd {
namespace {

namespace fs = std::filesystem;

TEST(Subject, FactorIsRoundedToTwentyStepsPerDecade) {
  EXPECT_EQ(subject_scale_factor(1.75), 1.0);
  EXPECT_EQ(subject_scale_factor(1.71), 1.0);  // the default sample's measured hull
  EXPECT_EQ(subject_scale_factor(1.75 * 1.02), 1.0);
  EXPECT_NEAR(subject_scale_factor(0.175), 0.1, 1e-15);
  EXPECT_NEAR(subject_scale_factor(3.5), std::pow(10.0, 6 / 20.0), 1e-12);
  EXPECT_DOUBLE_EQ(subject_scale_factor(3.5, 0), 2.0);
}

TEST(Subject, MeasuredOnMeshesAsTheMedianBox) {
  std::vector<Mesh> meshes = {test::make_box(Vec3f(0.2f, 0.3f, 1.7f)),
                              test::make_box(Vec3f(0.2f, 0.3f, 1.8f)),
                              test::make_box(Vec3f(2.5f, 0.3f, 0.4f)), Mesh{}};
  const Subject s = measure_subject(meshes, "frames");
  EXPECT_NEAR(s.size, 1.8, 1e-6);    // largest sides 1.7, 1.8, 2.5: the median
  EXPECT_NEAR(s.height, 1.7, 1e-6);  // vertical sides 1.7, 1.8, 0.4
  EXPECT_EQ(s.factor, 1.0);
  EXPECT_NE(s.source.find("3 mesh(es) of frames"), std::string::npos);
  EXPECT_THROW(measure_subject({Mesh{}}, "frames"), InputError);
}

TEST(Subject, ReadFromReconstructsRecordElseMeasured) {
  const fs::path dir = test::scratch_dir("subject_session");
  std::ofstream(dir / "session.yaml") << "name: s\nfps: 10\n";
  const Session session = Session::open(dir);
  int measured = 0;
  auto measure = [&] {
    ++measured;
    return measure_subject({test::make_box(Vec3f(0.1f, 0.1f, 0.08f))}, "template");
  };
  // No record anywhere: measured (a 10 cm object: factor 10^(-25/20)).
  Subject s = stage_subject(session, dir / "align", measure);
  EXPECT_EQ(measured, 1);
  EXPECT_NEAR(s.factor, std::pow(10.0, -25 / 20.0), 1e-12);

  fs::create_directories(dir / "reconstruct");
  std::ofstream(dir / "reconstruct" / kSubjectFile)
      << R"({"subject_size_m": 0.8, "subject_height_m": 0.5, "scale_factor": 0.4467})";
  s = stage_subject(session, dir / "align", measure);
  EXPECT_EQ(measured, 1);  // the session's record wins over measuring
  EXPECT_DOUBLE_EQ(s.size, 0.8);
  EXPECT_DOUBLE_EQ(s.factor, 0.4467);
  EXPECT_EQ(s.source, "reconstruct/subject.json");  // not where the session lies

  std::ofstream(dir / "reconstruct" / kSubjectFile) << R"({"subject_size_m": 0.8})";
  EXPECT_THROW(read_subject(dir / "reconstruct"), InputError);
  std::ofstream(dir / "reconstruct" / kSubjectFile)
      << R"({"subject_size_m": -1, "subject_height_m": 0.5, "scale_factor": 1})";
  EXPECT_THROW(read_subject(dir / "reconstruct"), InputError);
}

TEST(Subject, SpreadIndicesTakeTheMiddleOfEqualParts) {
  EXPECT_EQ(spread_indices(10, 5), (std::vector<std::size_t>{1, 3, 5, 7, 9}));
  EXPECT_EQ(spread_indices(3, 5), (std::vector<std::size_t>{0, 1, 2}));
  EXPECT_TRUE(spread_indices(0, 5).empty());
}

}  // namespace
}  // namespace fourd
