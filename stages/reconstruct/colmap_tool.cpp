#include "stages/reconstruct/colmap_tool.h"

#include <fcntl.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cerrno>
#include <cstdlib>
#include <cstring>
#include <deque>
#include <fmt/format.h>
#include <fstream>
#include <sstream>

#include "pipeline/core/error.h"
#include "pipeline/core/files.h"

extern char** environ;

namespace fourd::reconstruct {

std::string find_colmap(const std::string& configured) {
  const std::string name = configured.empty() ? "colmap" : configured;
  if (name.find('/') != std::string::npos) {
    return ::access(name.c_str(), X_OK) == 0 ? name : "";
  }
  const char* path = std::getenv("PATH");
  if (!path) return "";
  std::stringstream dirs(path);
  std::string dir;
  while (std::getline(dirs, dir, ':')) {
    if (dir.empty()) continue;
    std::filesystem::path candidate = std::filesystem::path(dir) / name;
    if (::access(candidate.c_str(), X_OK) == 0) return candidate.string();
  }
  return "";
}

int run_colmap(const std::string& executable, const std::string& command,
               const std::vector<std::string>& args, const std::filesystem::path& log) {
  std::vector<std::string> all = {executable, command};
  all.insert(all.end(), args.begin(), args.end());
  std::vector<char*> argv;
  for (auto& a : all) argv.push_back(a.data());
  argv.push_back(nullptr);

  posix_spawn_file_actions_t actions;
  posix_spawn_file_actions_init(&actions);
  posix_spawn_file_actions_addopen(&actions, STDOUT_FILENO, log.c_str(),
                                   O_WRONLY | O_CREAT | O_APPEND, 0644);
  posix_spawn_file_actions_adddup2(&actions, STDOUT_FILENO, STDERR_FILENO);
  posix_spawn_file_actions_addopen(&actions, STDIN_FILENO, "/dev/null", O_RDONLY, 0);
  pid_t pid = 0;
  int rc = ::posix_spawn(&pid, executable.c_str(), &actions, nullptr, argv.data(), environ);
  posix_spawn_file_actions_destroy(&actions);
  if (rc != 0) {
    throw IoError(fmt::format("cannot start {} {}: {}", executable, command, std::strerror(rc)));
  }
  int status = 0;
  while (::waitpid(pid, &status, 0) < 0) {
    if (errno != EINTR) {
      throw IoError(fmt::format("waiting for {} {} failed: {}", executable, command,
                                std::strerror(errno)));
    }
  }
  if (WIFEXITED(status)) return WEXITSTATUS(status);
  if (WIFSIGNALED(status)) return 128 + WTERMSIG(status);
  return 1;
}

void run_colmap_checked(const std::string& executable, const std::string& command,
                        const std::vector<std::string>& args, const std::filesystem::path& log) {
  int code = run_colmap(executable, command, args, log);
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
