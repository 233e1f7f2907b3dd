#pragma once
// The thin main() every stage executable shares: common command-line options, the stage log
// under logs/, timing, and one place that turns typed errors into messages and exit codes.
#include <CLI/CLI.hpp>

#include <functional>
#include <optional>
#include <string>

#include "pipeline/core/session.h"

namespace fourd {

// A take and frame range, so a farm can split per-frame work ("--take walk --frames 10:20").
struct FrameSelection {
  std::string take;       // empty: every take
  int first = 0;          // first frame (inclusive)
  int last = -1;          // last frame (inclusive); -1: to the end
  bool selects(const std::string& t, int frame) const {
    return (take.empty() || take == t) && frame >= first && (last < 0 || frame <= last);
  }
};

struct StageArgs {
  std::string session_dir;
  std::string oracle;  // non-empty: feed this stage ground-truth inputs (validation mode)
  FrameSelection selection;
  int threads = 0;     // 0: all cores
  bool verbose = false;
};

struct StageInfo {
  const char* name;         // "synth"
  const char* description;  // one paragraph for --help
  bool takes_frame_range = false;
  bool supports_oracle = false;
};

// Parses the common options plus those `add_options` registers, opens logs/<name>.log in the
// session, runs `body`, and returns the process exit code. Never throws.
int run_stage_main(int argc, char** argv, const StageInfo& info,
                   const std::function<void(CLI::App&)>& add_options,
                   const std::function<void(const Session&, const StageArgs&)>& body);

}  // namespace fourd
