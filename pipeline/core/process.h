#pragma once
// Running external command-line tools (COLMAP, ffmpeg): finding them and running them with
// their output in a log file.
#include <filesystem>
#include <string>
#include <vector>

namespace fourd {

// `name` itself when it names a path (contains '/'), otherwise the first executable of that
// name on PATH. Empty when it cannot be found or is not executable.
std::string find_executable(const std::string& name);

// Runs argv[0] (a path) with the arguments argv[1..], stdin from /dev/null, its stdout and
// stderr appended to `log`. Returns the exit code (128 + signal when killed). Throws IoError
// when the process cannot be started.
int run_process(const std::vector<std::string>& argv, const std::filesystem::path& log);

}  // namespace fourd
