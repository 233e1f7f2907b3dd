#include "pipeline/core/process.h"

#include <fcntl.h>
#include <fmt/format.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <csignal>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <optional>
#include <sstream>
#include <thread>

#include "pipeline/core/error.h"

extern char** environ;

namespace fourd {

std::string find_executable(const std::string& name) {
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

namespace {

// Waits for `pid` to end; returns its wait status. Throws IoError when waiting fails.
int wait_for(pid_t pid, const std::string& executable) {
  int status = 0;
  while (::waitpid(pid, &status, 0) < 0) {
    if (errno != EINTR) {
      throw IoError(fmt::format("waiting for {} failed: {}", executable, std::strerror(errno)));
    }
  }
  return status;
}

// As wait_for, but gives up after `seconds`: returns nullopt with the process still running.
std::optional<int> wait_for(pid_t pid, const std::string& executable, double seconds) {
  using Clock = std::chrono::steady_clock;
  const auto deadline = Clock::now() + std::chrono::duration<double>(seconds);
  auto pause = std::chrono::milliseconds(1);
  for (;;) {
    int status = 0;
    const pid_t done = ::waitpid(pid, &status, WNOHANG);
    if (done == pid) return status;
    if (done < 0 && errno != EINTR) {
      throw IoError(fmt::format("waiting for {} failed: {}", executable, std::strerror(errno)));
    }
    if (Clock::now() >= deadline) return std::nullopt;
    std::this_thread::sleep_for(pause);
    pause = std::min(pause * 2, std::chrono::milliseconds(100));
  }
}

}  // namespace

int run_process(const std::vector<std::string>& args, const std::filesystem::path& log,
                double timeout_seconds) {
  if (args.empty()) throw IoError("run_process: no program to run");
  std::vector<std::string> all = args;
  const std::string& executable = all.front();
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
    throw IoError(fmt::format("cannot start {}: {}", executable, std::strerror(rc)));
  }
  int status = 0;
  if (timeout_seconds > 0) {
    const std::optional<int> ended = wait_for(pid, executable, timeout_seconds);
    if (!ended) {
      ::kill(pid, SIGKILL);
      wait_for(pid, executable);
      const std::string message =
          fmt::format("{} did not finish within {} s and was killed", executable, timeout_seconds);
      std::ofstream(log, std::ios::app) << "\n[fourd] " << message << "\n";
      throw TimeoutError(message);
    }
    status = *ended;
  } else {
    status = wait_for(pid, executable);
  }
  if (WIFEXITED(status)) return WEXITSTATUS(status);
  if (WIFSIGNALED(status)) return 128 + WTERMSIG(status);
  return 1;
}

}  // namespace fourd
