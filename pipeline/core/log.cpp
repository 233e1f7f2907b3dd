#include "pipeline/core/log.h"

#include <atomic>
#include <cstdio>
#include <ctime>
#include <fstream>
#include <mutex>

namespace fourd::log {
namespace {

std::mutex g_mutex;
std::atomic<Level> g_level{Level::kInfo};
std::atomic<std::size_t> g_warnings{0};
std::ofstream g_file;

const char* level_tag(Level level) {
  switch (level) {
    case Level::kDebug: return "debug";
    case Level::kInfo: return "info";
    case Level::kWarn: return "WARNING";
    case Level::kError: return "ERROR";
  }
  return "";
}

}  // namespace

void set_level(Level level) { g_level = level; }
Level level() { return g_level; }
std::size_t warning_count() { return g_warnings; }

void open_file(const std::filesystem::path& path) {
  std::lock_guard lock(g_mutex);
  if (g_file.is_open()) g_file.close();
  if (!path.empty()) {
    std::filesystem::create_directories(path.parent_path());
    g_file.open(path, std::ios::app);
  }
}

std::string local_time(const char* format) {
  const std::time_t now = std::time(nullptr);
  std::tm tm{};
  localtime_r(&now, &tm);
  char buf[64];
  const std::size_t n = std::strftime(buf, sizeof buf, format, &tm);
  return std::string(buf, n);
}

void write(Level level, std::string_view message) {
  if (level == Level::kWarn) ++g_warnings;
  const std::string stamp = local_time("%H:%M:%S");
  std::lock_guard lock(g_mutex);
  const char* tag = level_tag(level);
  if (level == Level::kInfo) {
    std::fprintf(stderr, "[%s] %.*s\n", stamp.c_str(), static_cast<int>(message.size()),
                 message.data());
  } else {
    std::fprintf(stderr, "[%s] %s: %.*s\n", stamp.c_str(), tag, static_cast<int>(message.size()),
                 message.data());
  }
  if (g_file.is_open()) {
    g_file << '[' << stamp << "] " << tag << ": " << message << '\n';
    g_file.flush();
  }
}

Progress::Progress(std::string label, std::size_t total, double interval_seconds)
    : label_(std::move(label)),
      total_(total),
      interval_(interval_seconds),
      start_(std::chrono::steady_clock::now()),
      last_print_(start_) {}

Progress::~Progress() = default;

double Progress::elapsed_seconds() const {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count();
}

void Progress::step(std::size_t n) {
  std::size_t done;
  bool print = false;
  {
    std::lock_guard lock(g_mutex);
    done_ += n;
    done = done_;
    auto now = std::chrono::steady_clock::now();
    if (done >= total_) {
      print = !finished_;
      finished_ = true;
    } else if (std::chrono::duration<double>(now - last_print_).count() >= interval_) {
      print = true;
      last_print_ = now;
    }
  }
  if (!print) return;
  double t = elapsed_seconds();
  if (done >= total_) {
    info("{} [{}/{}] done in {:.1f} s", label_, done, total_, t);
  } else {
    double eta = done > 0 ? t * (static_cast<double>(total_) / done - 1.0) : 0.0;
    info("{} [{}/{}] {:.0f}% {:.1f} s, eta {:.1f} s", label_, done, total_,
         100.0 * done / std::max<std::size_t>(total_, 1), t, eta);
  }
}

}  // namespace fourd::log
