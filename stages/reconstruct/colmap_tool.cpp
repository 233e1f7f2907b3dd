#include "stages/reconstruct/colmap_tool.h"

#include <cstring>
#include <deque>
#include <fmt/format.h>
#include <fstream>
#include <sstream>

#include "pipeline/core/error.h"
#include "pipeline/core/files.h"
#include "pipeline/core/process.h"

namespace fourd::reconstruct {

std::string find_colmap(const std::string& configured) {
  return find_executable(configured.empty() ? "colmap" : configured);
}

int run_colmap(const std::string& executable, const std::string& command,
               const std::vector<std::string>& args, const std::filesystem::path& log,
               double timeout_seconds) {
  std::vector<std::string> all = {executable, command};
  all.insert(all.end(), args.begin(), args.end());
  constexpr int kAttempts = 2;
  for (int attempt = 1;; ++attempt) {
    try {
      return run_process(all, log, timeout_seconds);
    } catch (const TimeoutError&) {
      if (attempt == kAttempts) {
        throw TimeoutError(fmt::format(
            "COLMAP {} did not finish within {} s, {} times (killed each time), log {}:\n{}",
            command, timeout_seconds, kAttempts, log.string(), tail_of_file(log)));
      }
      std::ofstream(log, std::ios::app) << "[fourd] starting COLMAP " << command << " again\n";
    }
  }
}

void run_colmap_checked(const std::string& executable, const std::string& command,
                        const std::vector<std::string>& args, const std::filesystem::path& log,
                        double timeout_seconds) {
  int code = run_colmap(executable, command, args, log, timeout_seconds);
  if (code != 0) {
    throw SolverError(fmt::format("COLMAP {} failed (exit {}), log {}:\n{}", command, code,
                                  log.string(), tail_of_file(log)));
  }
}

void write_colmap_array(const std::filesystem::path& path, const cv::Mat& mat) {
  CV_Assert(mat.depth() == CV_32F);
  const int channels = mat.channels();
  std::string bytes = fmt::format("{}&{}&{}&", mat.cols, mat.rows, channels);
  std::vector<cv::Mat> planes;
  cv::split(mat, planes);
  for (const cv::Mat& plane : planes) {
    for (int r = 0; r < plane.rows; ++r) {
      bytes.append(reinterpret_cast<const char*>(plane.ptr<float>(r)), plane.cols * sizeof(float));
    }
  }
  write_file_atomic(path, bytes);
}

cv::Mat read_colmap_array(const std::filesystem::path& path) {
  const std::string bytes = read_file(path);
  int dims[3] = {0, 0, 0};
  std::size_t pos = 0;
  for (int& d : dims) {
    std::size_t amp = bytes.find('&', pos);
    if (amp == std::string::npos || amp - pos > 10) {
      throw InputError(fmt::format("{}: not a COLMAP array (no 'width&height&channels&' header)",
                                   path.string()));
    }
    d = std::atoi(bytes.substr(pos, amp - pos).c_str());
    pos = amp + 1;
  }
  const int width = dims[0], height = dims[1], channels = dims[2];
  if (width <= 0 || height <= 0 || channels <= 0 || channels > 4) {
    throw InputError(fmt::format("{}: bad COLMAP array size {}x{}x{}", path.string(), width,
                                 height, channels));
  }
  const std::size_t plane = static_cast<std::size_t>(width) * height;
  if (bytes.size() - pos != plane * channels * sizeof(float)) {
    throw InputError(fmt::format("{}: COLMAP array of {}x{}x{} floats holds {} bytes", path.string(),
                                 width, height, channels, bytes.size() - pos));
  }
  std::vector<cv::Mat> planes;
  for (int c = 0; c < channels; ++c) {
    cv::Mat p(height, width, CV_32F);
    std::memcpy(p.data, bytes.data() + pos + c * plane * sizeof(float), plane * sizeof(float));
    planes.push_back(p);
  }
  cv::Mat out;
  cv::merge(planes, out);
  return out;
}

std::string tail_of_file(const std::filesystem::path& path, int lines) {
  std::ifstream in(path);
  std::deque<std::string> last;
  std::string line;
  while (std::getline(in, line)) {
    last.push_back(line);
    if (static_cast<int>(last.size()) > lines) last.pop_front();
  }
  std::string out;
  for (const auto& l : last) out += "  " + l + "\n";
  return out;
}

}  // namespace fourd::reconstruct
