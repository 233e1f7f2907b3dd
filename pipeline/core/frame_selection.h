#pragma once
// Which frames one job of a per-frame stage processes: a take and frame ranges
// ("--take walk --frames 0:7,16:23"). The `fourd` driver and the generated Snakemake workflow
// split per-frame stages into such jobs; the stage checks the selection against the capture
// before doing any work.
#include <string>
#include <vector>

#include "pipeline/core/capture.h"

namespace fourd {

struct FrameRange {
  int first = 0;  // inclusive
  int last = -1;  // inclusive; -1: to the end of the take
};

struct FrameSelection {
  std::string take;                // empty: every take
  std::vector<FrameRange> ranges;  // empty: every frame; sorted, not overlapping

  // Nothing narrowed: the job is the whole stage.
  bool whole() const { return take.empty() && ranges.empty(); }
  bool selects(const std::string& t, int frame) const;
  // The --frames text ("0:7,16:23"; "" when every frame).
  std::string frames_text() const;
  // A name for the job's files (its log): "walk.0-7", "walk.0-7_16-23", "all.0-7"; "" when whole.
  std::string job_suffix() const;
};

// The log file name of one job: "<stage>.log" for a whole stage (or its --finish job),
// "<stage>.<take>.<first>-<last>.log" for a frame-range job, "<stage>.<part>.log" for a part
// of a stage split along a tree ("align.tree", "align.branch2"). `stage` names the variant
// ("reconstruct_oracle"). Stages write it under logs/; the driver and the workflow point to it.
std::string job_log_name(const std::string& stage, const FrameSelection& selection,
                         const std::string& part = {});

// Parses --take/--frames ("FIRST:LAST", "FIRST:", "N", comma-separated). Throws UsageError
// for text that is not a range, an empty or negative range, or ranges that overlap.
FrameSelection parse_frame_selection(const std::string& take, const std::string& frames);

// Checks the selection against the capture: the take exists, and every range lies within it
// (without --take, within the longest take). Throws InputError naming the take and its frames.
void check_frame_selection(const FrameSelection& selection, const CaptureIndex& capture);

}  // namespace fourd
