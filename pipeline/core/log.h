#pragma once
// One small logging and progress API for every stage. Messages go to stderr and, when a
// log file is open, to that file too (the driver opens logs/<stage>.log).
#include <fmt/format.h>

#include <chrono>
#include <cstddef>
#include <filesystem>
#include <string>
#include <string_view>

namespace fourd::log {

enum class Level { kDebug = 0, kInfo = 1, kWarn = 2, kError = 3 };

void set_level(Level level);
Level level();
// Also write every message to this file (appending). An empty path closes it.
void open_file(const std::filesystem::path& path);
void write(Level level, std::string_view message);
// Number of warnings written since start: stages report it at the end.
std::size_t warning_count();
// The local wall-clock time now, formatted by std::strftime (thread-safe, unlike
// std::localtime).
std::string local_time(const char* format = "%Y-%m-%d %H:%M:%S");

template <typename... Args>
void debug(fmt::format_string<Args...> f, Args&&... args) {
  if (level() <= Level::kDebug) write(Level::kDebug, fmt::format(f, std::forward<Args>(args)...));
}
template <typename... Args>
void info(fmt::format_string<Args...> f, Args&&... args) {
  if (level() <= Level::kInfo) write(Level::kInfo, fmt::format(f, std::forward<Args>(args)...));
}
template <typename... Args>
void warn(fmt::format_string<Args...> f, Args&&... args) {
  write(Level::kWarn, fmt::format(f, std::forward<Args>(args)...));
}
template <typename... Args>
void error(fmt::format_string<Args...> f, Args&&... args) {
  write(Level::kError, fmt::format(f, std::forward<Args>(args)...));
}

// Progress of a long loop: "label [k/n] 42% 3.1 s, eta 4.2 s", printed at most every
// `interval` seconds and once at the end. Thread-safe step().
class Progress {
 public:
  Progress(std::string label, std::size_t total, double interval_seconds = 2.0);
  ~Progress();
  Progress(const Progress&) = delete;
  Progress& operator=(const Progress&) = delete;
  void step(std::size_t n = 1);
  double elapsed_seconds() const;

 private:
  std::string label_;
  std::size_t total_;
  double interval_;
  std::size_t done_ = 0;
  std::chrono::steady_clock::time_point start_;
  std::chrono::steady_clock::time_point last_print_;
  bool finished_ = false;
};

// Wall-clock timer for "took 1.2 s" messages.
class Timer {
 public:
  Timer() : start_(std::chrono::steady_clock::now()) {}
  double seconds() const {
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count();
  }

 private:
  std::chrono::steady_clock::time_point start_;
};

}  // namespace fourd::log
