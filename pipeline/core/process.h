#pragma once
// Running external command-line tools (COLMAP, ffmpeg): finding them and running them with
// their output in a log file.
#include <filesystem>
#include <string>
#include <vector>

#include "pipeline/core/error.h"

namespace fourd {

// An external tool that ran past its time limit and was killed.
class TimeoutError : public SolverError {
 public:
  using SolverError::SolverError;
};

// `name` itself when it names a path (contains '/'), otherwise the first executable of that
// name on PATH. Empty when it cannot be found or is not executable.
std::string find_executable(const std::string& name);

// Runs argv[0] (a path) with the arguments argv[1..], stdin from /dev/null, its stdout and
// stderr appended to `log`. Returns the exit code (128 + signal when killed). Throws IoError
// when the process cannot be started. With `timeout_seconds` > 0, a process still running after
// that long is killed (a line in `log` says so) and TimeoutError is thrown.
int run_process(const std::vector<std::string>& argv, const std::filesystem::path& log,
                double timeout_seconds = 0);

}  // namespace fourd
