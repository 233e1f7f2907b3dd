#pragma once
// Running the COLMAP command-line tool, and the files it exchanges with us: dense workspace
// arrays (depth/normal maps) and text sparse models with 2D-3D tracks.
#include <filesystem>
#include <opencv2/core.hpp>
#include <string>
#include <vector>

namespace fourd::reconstruct {

// The colmap executable: `configured` itself when it names a path (contains '/'), otherwise
// searched on PATH. Empty when it cannot be found or is not executable.
std::string find_colmap(const std::string& configured);

// Runs `executable command args...`, appending its stdout and stderr to `log`. Returns the exit
// code (128 + signal when killed). Throws IoError when the process cannot be started. With
// `timeout_seconds` > 0, a run still going after that long is killed and started once more
// (COLMAP's tools can hang, rarely, where a second run finishes; they pick up what the killed
// run left in the database); a second timeout throws TimeoutError.
int run_colmap(const std::string& executable, const std::string& command,
               const std::vector<std::string>& args, const std::filesystem::path& log,
               double timeout_seconds);

// Runs it and throws SolverError("COLMAP <command> failed (exit N): <last lines of the log>")
// unless it exits with 0.
void run_colmap_checked(const std::string& executable, const std::string& command,
                        const std::vector<std::string>& args, const std::filesystem::path& log,
                        double timeout_seconds);

// COLMAP's dense workspace array format (mvs/mat.h): ASCII "width&height&channels&" then float32
// values, one channel plane after another, rows top to bottom. `mat` is CV_32FC1..CV_32FC4.
void write_colmap_array(const std::filesystem::path& path, const cv::Mat& mat);
cv::Mat read_colmap_array(const std::filesystem::path& path);

// The last `lines` lines of a text file ("" when it cannot be read): for error messages.
std::string tail_of_file(const std::filesystem::path& path, int lines = 8);

}  // namespace fourd::reconstruct
