// Frame selections (--take/--frames): parsing, job names and the check against the capture.
#include "pipeline/core/frame_selection.h"

#include <gtest/gtest.h>

#include <string>

#include "pipeline/core/capture.h"
#include "pipeline/core/error.h"

namespace fourd {
namespace {

CaptureIndex two_takes() {
  CaptureIndex capture;
  capture.takes = {{"jump", 3, {}}, {"walk", 10, {}}};
  return capture;
}

TEST(FrameSelection, ParsesRangesAndNamesTheJob) {
  FrameSelection s = parse_frame_selection("walk", "16:23,0:7");
  ASSERT_EQ(s.ranges.size(), 2u);
  EXPECT_EQ(s.ranges[0].first, 0);  // sorted
  EXPECT_EQ(s.frames_text(), "0:7,16:23");
  EXPECT_EQ(s.job_suffix(), "walk.0-7_16-23");
  EXPECT_EQ(job_log_name("reconstruct_oracle", s), "reconstruct_oracle.walk.0-7_16-23.log");
  EXPECT_TRUE(s.selects("walk", 7));
  EXPECT_FALSE(s.selects("walk", 8));
  EXPECT_TRUE(s.selects("walk", 16));
  EXPECT_FALSE(s.selects("jump", 0));
  EXPECT_TRUE(parse_frame_selection("", "").whole());
  EXPECT_EQ(job_log_name("segment", parse_frame_selection("", "")), "segment.log");
  FrameSelection open = parse_frame_selection("walk", "5:");
  EXPECT_TRUE(open.selects("walk", 500));
  EXPECT_FALSE(open.selects("walk", 4));
  EXPECT_EQ(parse_frame_selection("walk", "4").frames_text(), "4:4");
}

TEST(FrameSelection, BadTextEmptyAndOverlappingRangesAreUsageErrors) {
  for (const char* bad : {"a:b", "3:1", "-2:4", "1:2x", "0:9,5:12", "0:,20:30", ""}) {
    if (std::string(bad).empty()) continue;
    try {
      parse_frame_selection("walk", bad);
      ADD_FAILURE() << bad << " was accepted";
    } catch (const UsageError& e) {
      EXPECT_EQ(e.exit_code(), kExitUsage);
      EXPECT_NE(std::string(e.what()).find(bad), std::string::npos) << e.what();
    }
  }
  EXPECT_NO_THROW(parse_frame_selection("walk", "0:9,10:12"));  // touching is fine
}

TEST(FrameSelection, RangeOutsideTheTakeOrUnknownTakeIsAnInputError) {
  const CaptureIndex capture = two_takes();
  EXPECT_NO_THROW(check_frame_selection(parse_frame_selection("walk", "8:9"), capture));
  EXPECT_NO_THROW(check_frame_selection(parse_frame_selection("", "0:9"), capture));
  try {
    check_frame_selection(parse_frame_selection("jump", "2:5"), capture);
    ADD_FAILURE() << "accepted";
  } catch (const InputError& e) {
    EXPECT_EQ(e.exit_code(), kExitInput);
    EXPECT_NE(std::string(e.what()).find("take jump has frames 0:2"), std::string::npos) << e.what();
  }
  EXPECT_THROW(check_frame_selection(parse_frame_selection("jump", "3:"), capture), InputError);
  EXPECT_THROW(check_frame_selection(parse_frame_selection("run", "0:1"), capture), InputError);
  EXPECT_THROW(check_frame_selection(parse_frame_selection("", "10:11"), capture), InputError);
}

}  // namespace
}  // namespace fourd
