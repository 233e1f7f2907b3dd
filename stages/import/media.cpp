#include "stages/import/media.h"

#include <fmt/format.h>
#include <fnmatch.h>

#include <algorithm>
#include <charconv>
#include <cmath>
#include <opencv2/imgproc.hpp>
#include <opencv2/videoio.hpp>
#include <regex>

#include "pipeline/core/error.h"
#include "pipeline/core/image_io.h"

namespace fourd::import {
namespace {

namespace fs = std::filesystem;

std::string lower_extension(const fs::path& p) {
  std::string e = p.extension().string();
  std::transform(e.begin(), e.end(), e.begin(), [](unsigned char c) { return std::tolower(c); });
  return e;
}

std::string join(const std::vector<std::string>& items) {
  std::string out;
  for (const auto& s : items) out += (out.empty() ? "" : ", ") + s;
  return out.empty() ? "(none)" : out;
}

void replace_all(std::string* s, const std::string& from, const std::string& to) {
  for (std::size_t at = s->find(from); at != std::string::npos; at = s->find(from, at + to.size())) {
    s->replace(at, from.size(), to);
  }
}

cv::VideoCapture open_video(const fs::path& video, const std::string& camera) {
  if (!fs::is_regular_file(video)) {
    throw IoError(fmt::format("{} (camera {}): no such video file", video.string(), camera));
  }
  cv::VideoCapture capture(video.string(), cv::CAP_FFMPEG);
  if (!capture.isOpened()) capture.open(video.string(), cv::CAP_ANY);
  if (!capture.isOpened()) {
    throw InputError(fmt::format("{} (camera {}): not a video OpenCV can read", video.string(), camera));
  }
  return capture;
}

}  // namespace

std::string Sequence::describe() const {
  if (!video.empty()) return video.string();
  if (images.empty()) return "(no images)";
  return fmt::format("{} ... ({} images)", images.front().string(), images.size());
}

bool natural_less(const std::string& a, const std::string& b) {
  std::size_t i = 0, j = 0;
  while (i < a.size() && j < b.size()) {
    if (std::isdigit(static_cast<unsigned char>(a[i])) && std::isdigit(static_cast<unsigned char>(b[j]))) {
      std::size_t ei = i, ej = j;
      while (ei < a.size() && std::isdigit(static_cast<unsigned char>(a[ei]))) ++ei;
      while (ej < b.size() && std::isdigit(static_cast<unsigned char>(b[ej]))) ++ej;
      const std::string na = a.substr(i, ei - i), nb = b.substr(j, ej - j);
      const std::string ta = na.substr(std::min(na.find_first_not_of('0'), na.size()));
      const std::string tb = nb.substr(std::min(nb.find_first_not_of('0'), nb.size()));
      if (ta.size() != tb.size()) return ta.size() < tb.size();
      if (ta != tb) return ta < tb;
      if (na.size() != nb.size()) return na.size() < nb.size();
      i = ei, j = ej;
      continue;
    }
    if (a[i] != b[j]) return a[i] < b[j];
    ++i, ++j;
  }
  return a.size() - i < b.size() - j;
}

const std::vector<std::string>& video_extensions() {
  static const std::vector<std::string> e = {".mp4", ".avi", ".mov", ".mkv", ".m4v", ".mpg",
                                             ".mpeg", ".webm", ".mxf", ".wmv", ".ts", ".mts"};
  return e;
}

const std::vector<std::string>& image_extensions() {
  static const std::vector<std::string> e = {".png", ".jpg", ".jpeg", ".bmp", ".tif", ".tiff",
                                             ".exr", ".webp", ".pgm", ".ppm"};
  return e;
}

bool is_video_file(const fs::path& path) {
  const auto& v = video_extensions();
  return std::find(v.begin(), v.end(), lower_extension(path)) != v.end();
}

std::vector<fs::path> list_files(const std::vector<fs::path>& paths, const std::vector<std::string>& extensions) {
  std::vector<fs::path> out;
  for (const fs::path& p : paths) {
    if (fs::is_directory(p)) {
      for (const auto& entry : fs::directory_iterator(p)) {
        const std::string name = entry.path().filename().string();
        if (!entry.is_regular_file() || name.empty() || name[0] == '.') continue;
        if (std::find(extensions.begin(), extensions.end(), lower_extension(entry.path())) != extensions.end()) {
          out.push_back(entry.path());
        }
      }
    } else if (fs::is_regular_file(p)) {
      out.push_back(p);
    } else {
      throw IoError(fmt::format("{}: no such file or folder", p.string()));
    }
  }
  std::sort(out.begin(), out.end(), [](const fs::path& a, const fs::path& b) {
    return natural_less(a.string(), b.string());
  });
  return out;
}

std::map<std::string, std::vector<fs::path>> match_files_to_cameras(
    const std::vector<fs::path>& files, const std::map<std::string, fs::path>& explicit_files,
    const std::vector<Camera>& cameras, const std::string& what, bool several) {
  std::vector<std::string> names;
  for (const Camera& c : cameras) names.push_back(c.name);
  std::map<std::string, std::vector<fs::path>> out;
  for (const auto& [camera, file] : explicit_files) {
    if (std::find(names.begin(), names.end(), camera) == names.end()) {
      throw InputError(fmt::format("--{} {}={}: the calibration has no camera {} (its cameras: {})",
                                   what, camera, file.string(), camera, join(names)));
    }
    out[camera].push_back(file);
  }
  std::vector<std::string> orphans;
  for (const fs::path& file : files) {
    const std::string stem = file.stem().string();
    const std::string* best = nullptr;
    for (const std::string& name : names) {
      if (stem.find(name) != std::string::npos && (!best || name.size() > best->size())) best = &name;
    }
    if (!best) {
      orphans.push_back(file.string());
      continue;
    }
    if (explicit_files.count(*best)) continue;  // the explicit file wins
    out[*best].push_back(file);
  }
  std::vector<std::string> missing;
  for (const std::string& name : names) {
    if (!out.count(name)) missing.push_back(name);
  }
  if (!orphans.empty() || !missing.empty()) {
    std::vector<std::string> matched;
    for (const auto& [camera, list] : out) matched.push_back(camera);
    throw InputError(fmt::format(
        "{}s and cameras do not match: {} with no camera: {}; cameras with no {}: {} (the "
        "calibration's cameras: {}; a {} belongs to the camera whose name its file name contains, "
        "or give --{} CAMERA=FILE)",
        what, what, join(orphans), what, join(missing), join(names), what, what));
  }
  if (!several) {
    for (const auto& [camera, list] : out) {
      if (list.size() > 1) {
        std::vector<std::string> listed;
        for (const auto& f : list) listed.push_back(f.string());
        throw InputError(fmt::format("camera {} has {} {}s: {} (give one, or --{} {}=FILE)", camera,
                                     list.size(), what, join(listed), what, camera));
      }
    }
  }
  return out;
}

std::vector<fs::path> images_from_pattern(const std::string& pattern, const std::string& camera) {
  std::string path = pattern;
  replace_all(&path, "{camera}", camera);
  const fs::path p(path);
  const fs::path dir = p.has_parent_path() ? p.parent_path() : fs::path(".");
  const std::string name = p.filename().string();
  if (dir.string().find_first_of("*?{") != std::string::npos) {
    throw UsageError(fmt::format("image pattern '{}': only the file name may hold {{frame}} or a "
                                 "glob, not the folders",
                                 pattern));
  }
  // {frame} / {frame:0Nd} become a captured number; the rest is a glob.
  static const std::regex kFrame(R"(\{frame(?::0?(\d+)d)?\})");
  std::smatch m;
  const bool numbered = std::regex_search(name, m, kFrame);
  std::regex number_regex;
  std::string glob = name;
  if (numbered) {
    const std::string digits = m[1].matched ? fmt::format("{{{}}}", m[1].str()) : "+";
    std::string before = m.prefix().str(), after = m.suffix().str();
    auto escape = [](const std::string& s) {
      std::string out;
      for (char c : s) {
        if (c == '*') out += ".*";
        else if (c == '?') out += '.';
        else if (std::string("\\^$.|+()[]{}").find(c) != std::string::npos) out += std::string("\\") + c;
        else out += c;
      }
      return out;
    };
    number_regex = std::regex(escape(before) + "(\\d" + digits + ")" + escape(after));
  }
  if (!fs::is_directory(dir)) {
    throw InputError(fmt::format("image pattern '{}' (camera {}): no folder {}", pattern, camera, dir.string()));
  }
  std::vector<std::pair<long long, fs::path>> numbered_files;
  std::vector<fs::path> files;
  for (const auto& entry : fs::directory_iterator(dir)) {
    if (!entry.is_regular_file()) continue;
    const std::string file = entry.path().filename().string();
    if (numbered) {
      std::smatch fm;
      if (std::regex_match(file, fm, number_regex)) numbered_files.emplace_back(std::stoll(fm[1].str()), entry.path());
    } else if (fnmatch(glob.c_str(), file.c_str(), 0) == 0) {
      files.push_back(entry.path());
    }
  }
  if (numbered) {
    std::sort(numbered_files.begin(), numbered_files.end());
    for (auto& [n, f] : numbered_files) files.push_back(f);
  } else {
    std::sort(files.begin(), files.end(), [](const fs::path& a, const fs::path& b) {
      return natural_less(a.filename().string(), b.filename().string());
    });
  }
  if (files.empty()) {
    throw InputError(fmt::format("image pattern '{}' (camera {}): no file in {} matches {}", pattern,
                                 camera, dir.string(), name));
  }
  return files;
}

TakeSpec parse_take(const std::string& text, int default_first, int default_last, int step,
                    std::optional<double> from_seconds, std::optional<double> to_seconds) {
  TakeSpec take;
  take.step = step;
  const auto eq = text.find('=');
  take.name = text.substr(0, eq);
  static const std::regex kName(R"([A-Za-z0-9_][A-Za-z0-9_.-]*)");
  if (!std::regex_match(take.name, kName)) {
    throw UsageError(fmt::format("--take '{}': a take name is letters, digits, '_', '.', '-'", text));
  }
  if (step < 1) throw UsageError(fmt::format("--step {}: at least 1", step));
  if (eq == std::string::npos) {
    take.first = default_first, take.last = default_last;
    take.from_seconds = from_seconds, take.to_seconds = to_seconds;
  } else {
    const std::string range = text.substr(eq + 1);
    static const std::regex kFrames(R"((\d+):(\d*))");
    static const std::regex kSeconds(R"((\d+(?:\.\d*)?)s:(?:(\d+(?:\.\d*)?)s)?)");
    std::smatch m;
    if (std::regex_match(range, m, kFrames)) {
      take.first = std::stoi(m[1]);
      take.last = m[2].length() ? std::stoi(m[2]) : -1;
    } else if (std::regex_match(range, m, kSeconds)) {
      take.from_seconds = std::stod(m[1]);
      if (m[2].matched) take.to_seconds = std::stod(m[2]);
    } else {
      throw UsageError(fmt::format("--take '{}': expected NAME, NAME=FIRST:LAST (frames, inclusive; "
                                   "LAST may be empty) or NAME=FROMs:TOs (seconds)",
                                   text));
    }
  }
  if (take.last >= 0 && take.last < take.first) {
    throw UsageError(fmt::format("--take '{}': the range {}:{} is empty", text, take.first, take.last));
  }
  if (take.from_seconds && take.to_seconds && *take.to_seconds <= *take.from_seconds) {
    throw UsageError(fmt::format("--take '{}': the time range is empty", text));
  }
  return take;
}

TakeSpec resolve_times(const TakeSpec& take, double fps) {
  TakeSpec out = take;
  if (!take.from_seconds && !take.to_seconds) return out;
  if (!(fps > 0)) throw UsageError(fmt::format("take {}: a time range needs the frame rate (give --fps)", take.name));
  if (take.from_seconds) out.first = static_cast<int>(std::lround(*take.from_seconds * fps));
  out.last = take.to_seconds ? static_cast<int>(std::lround(*take.to_seconds * fps)) - 1 : -1;
  out.from_seconds.reset();
  out.to_seconds.reset();
  if (out.last >= 0 && out.last < out.first) out.last = out.first;
  return out;
}

double video_fps(const fs::path& video, const std::string& camera) {
  cv::VideoCapture capture = open_video(video, camera);
  const double fps = capture.get(cv::CAP_PROP_FPS);
  return std::isfinite(fps) && fps > 0 ? fps : 0.0;
}

int read_sequence(const Sequence& sequence, const std::vector<TakeSpec>& takes, int flags,
                  const FrameSink& sink) {
  bool open_end = false;
  int needed = 0;  // frames the closed ranges need
  for (const TakeSpec& t : takes) {
    if (t.last < 0) open_end = true;
    needed = std::max(needed, (t.last < 0 ? t.first : t.last) + 1);
  }
  auto deliver = [&](int source, const cv::Mat& image) {
    for (std::size_t k = 0; k < takes.size(); ++k) {
      const TakeSpec& t = takes[k];
      if (source < t.first || (t.last >= 0 && source > t.last) || (source - t.first) % t.step != 0) continue;
      sink(k, (source - t.first) / t.step, source, image);
    }
  };
  auto selected = [&](int source) {
    for (const TakeSpec& t : takes) {
      if (source >= t.first && (t.last < 0 || source <= t.last) && (source - t.first) % t.step == 0) return true;
    }
    return false;
  };
  int count = 0;
  if (!sequence.video.empty()) {
    cv::VideoCapture capture = open_video(sequence.video, sequence.camera);
    cv::Mat frame;
    for (; open_end || count < needed; ++count) {
      if (!capture.grab()) break;
      if (!selected(count)) continue;
      if (!capture.retrieve(frame) || frame.empty()) {
        throw InputError(fmt::format("{} (camera {}): frame {} cannot be decoded", sequence.video.string(),
                                     sequence.camera, count));
      }
      deliver(count, frame);
    }
  } else {
    for (; count < static_cast<int>(sequence.images.size()) && (open_end || count < needed); ++count) {
      if (!selected(count)) continue;
      deliver(count, read_image(sequence.images[count], flags));
    }
  }
  for (const TakeSpec& t : takes) {
    const int last = t.last < 0 ? t.first : t.last;
    if (last >= count) {
      throw InputError(fmt::format(
          "{} (camera {}): {} frames, but take {} asks for frames {}:{}", sequence.describe(),
          sequence.camera, count, t.name, t.first, t.last < 0 ? std::string() : std::to_string(t.last)));
    }
  }
  return count;
}

std::vector<cv::Mat> sample_video(const fs::path& video, const std::string& camera, int count) {
  int total = 0;
  {
    cv::VideoCapture capture = open_video(video, camera);
    while (capture.grab()) ++total;
  }
  if (total == 0) throw InputError(fmt::format("{} (camera {}): the video has no frames", video.string(), camera));
  std::vector<int> picks;  // evenly spread, first and last included
  const int n = std::min(count, total);
  for (int i = 0; i < n; ++i) picks.push_back(n == 1 ? 0 : static_cast<int>(static_cast<long long>(i) * (total - 1) / (n - 1)));
  std::vector<cv::Mat> out;
  cv::VideoCapture capture = open_video(video, camera);
  cv::Mat frame;
  for (int f = 0, next = 0; next < n && capture.grab(); ++f) {
    if (f != picks[next]) continue;
    if (!capture.retrieve(frame) || frame.empty()) {
      throw InputError(fmt::format("{} (camera {}): frame {} cannot be decoded", video.string(), camera, f));
    }
    out.push_back(frame.clone());
    ++next;
  }
  if (static_cast<int>(out.size()) != n) {
    throw InputError(fmt::format("{} (camera {}): the video ended early on the second read", video.string(), camera));
  }
  return out;
}

}  // namespace fourd::import
