// The runtime's validation (stages/validate/validate_paths.cpp) on a session holding the
// procedural test graph as its asset and control scripts in play/.
#include <gtest/gtest.h>
#include <stdlib.h>

#include <fstream>

#include "pipeline/core/error.h"
#include "pipeline/core/files.h"
#include "pipeline/core/image_io.h"
#include "runtime/asset.h"
#include "stages/validate/validate.h"
#include "tests/graph/test_graph.h"

namespace fourd::validate {
namespace {

namespace fs = std::filesystem;

class ValidatePathsTest : public ::testing::Test {
 protected:
  void SetUp() override {
    std::string pattern = (fs::temp_directory_path() / "fourd_validate_paths_XXXXXX").string();
    ASSERT_NE(::mkdtemp(pattern.data()), nullptr);
    root_ = pattern;
    write_file_atomic(root_ / "session.yaml", "name: paths\n");
    Asset asset;
    asset.graph = test::make_test_graph(true);
    ensure_directory(root_ / "asset_oracle");
    save_asset(root_ / "asset_oracle" / "motion_graph.fourd", asset);
    ensure_directory(root_ / "play");
    // A path with a gap, a timeline (no path: not played) and a path that needs a space the
    // asset lacks (left out, said so).
    write_file_atomic(root_ / "play" / "gap.txt",
                      "start locomotion 1.2\npath 0 0\ncurve 1 0 2 0 3 0 speed 1.2\n"
                      "curve 3.3 0 3.6 0 3.9 0 gap\ncurve 5 0 6 0 7 0\n");
    write_file_atomic(root_ / "play" / "timeline.txt", "start locomotion 1.2\nat 1 param 1.5\n");
    write_file_atomic(root_ / "play" / "swim.txt", "start swim 1\npath 0 0\ncurve 1 0 2 0 3 0\n");
  }
  void TearDown() override { fs::remove_all(root_); }

  StageReport validate() {
    const Session session = Session::open(root_);
    const ValidateOptions options;
    ensure_directory(session.reports_dir());
    return validate_paths({session, options, session.reports_dir()});
  }

  double metric(const StageReport& r, const std::string& name) {
    for (const Metric& m : r.metrics) {
      if (m.name == name) {
        EXPECT_EQ(m.input, InputKind::kOracle) << name;
        return m.value;
      }
    }
    ADD_FAILURE() << "no metric " << name;
    return -1;
  }

  fs::path root_;
};

TEST_F(ValidatePathsTest, PlaysThePathsAndDrawsThePlotAndTheFilmstrip) {
  const StageReport r = validate();
  ASSERT_TRUE(r.present);
  EXPECT_EQ(metric(r, "finished"), 1);
  EXPECT_LE(metric(r, "gap_max_error_m"), 0.25);
  EXPECT_LE(std::abs(metric(r, "gap_length_error_pct")), 2.0);
  EXPECT_LE(std::abs(metric(r, "gap_jump_offset_m")), 0.3);
  EXPECT_EQ(metric(r, "max_error_m"), metric(r, "gap_max_error_m"));
  for (const Metric& m : r.metrics) EXPECT_EQ(m.name.find("timeline"), std::string::npos);
  EXPECT_NE(r.details.find("unknown motion space 'swim'"), std::string::npos) << r.details;
  // The plot and the filmstrip exist and are real images; the player's logs are kept.
  ASSERT_EQ(r.pictures.size(), 2u);
  for (const Picture& p : r.pictures) {
    const cv::Mat image = read_image(root_ / "reports" / p.file);
    EXPECT_GT(image.cols, 300) << p.file;
    EXPECT_GT(image.rows, 200) << p.file;
  }
  EXPECT_TRUE(fs::exists(root_ / "reports" / "plays" / "oracle_gap" / "frames.csv"));
}

TEST_F(ValidatePathsTest, MalformedScriptNamesItsLine) {
  write_file_atomic(root_ / "play" / "bad.txt", "start locomotion 1.2\npath 0 0\ncurve 1 0 2\n");
  try {
    validate();
    FAIL() << "a malformed script was accepted";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("bad.txt:3:"), std::string::npos) << e.what();
  }
}

TEST_F(ValidatePathsTest, NoAssetIsSkipped) {
  fs::remove_all(root_ / "asset_oracle");
  const StageReport r = validate();
  EXPECT_FALSE(r.present);
  EXPECT_TRUE(r.metrics.empty());
}

}  // namespace
}  // namespace fourd::validate
