#include "pipeline/core/log.h"

#include <gtest/gtest.h>

#include <fstream>
#include <regex>
#include <sstream>

#include "tests/scratch_dir.h"

namespace fourd {
namespace {

TEST(Log, LocalTimeIsFormattedAsAsked) {
  EXPECT_TRUE(
      std::regex_match(log::local_time(), std::regex(R"(\d{4}-\d{2}-\d{2} \d{2}:\d{2}:\d{2})")));
  EXPECT_TRUE(std::regex_match(log::local_time("%H:%M"), std::regex(R"(\d{2}:\d{2})")));
  EXPECT_EQ(log::local_time("no conversions"), "no conversions");
}

TEST(Log, AWarningGoesToTheLogFileStampedAndIsCounted) {
  const std::filesystem::path file = test::scratch_dir("log") / "stage.log";
  const std::size_t warnings = log::warning_count();
  log::open_file(file);
  log::warn("frame {} of {}: no foreground", 7, "walk");
  log::open_file({});  // closes it
  EXPECT_EQ(log::warning_count(), warnings + 1);
  std::ifstream in(file);
  std::stringstream text;
  text << in.rdbuf();
  EXPECT_TRUE(std::regex_match(
      text.str(), std::regex(R"(\[\d{2}:\d{2}:\d{2}\] WARNING: frame 7 of walk: no foreground\n)")))
      << text.str();
}

}  // namespace
}  // namespace fourd
