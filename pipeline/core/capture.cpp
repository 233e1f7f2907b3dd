#include "pipeline/core/capture.h"

#include <fmt/format.h>

#include <algorithm>
#include <cctype>
#include <charconv>
#include <optional>

#include "pipeline/core/error.h"
#include "pipeline/core/image_io.h"

namespace fourd {
namespace {

namespace fs = std::filesystem;

bool is_hidden(const fs::path& p) {
  const std::string name = p.filename().string();
  return !name.empty() && name[0] == '.';
}

// The frame number of "000042.png"; nothing for any other name (so "42.png", "000042.jpg",
// temp files and notes are not frames).
std::optional<int> frame_number(const fs::path& file) {
  if (file.extension() != ".png") return std::nullopt;
  const std::string stem = file.stem().string();
  if (stem.size() < 6 || stem.size() > 9) return std::nullopt;
  if (!std::all_of(stem.begin(), stem.end(), [](unsigned char c) { return std::isdigit(c); })) {
    return std::nullopt;
  }
  int frame = 0;
  std::from_chars(stem.data(), stem.data() + stem.size(), frame);
  if (frame_name(frame) != stem) return std::nullopt;  // e.g. "0000042": not how we name frames
  return frame;
}

std::vector<fs::path> sorted_entries(const fs::path& dir) {
  std::vector<fs::path> entries;
  std::error_code ec;
  for (fs::directory_iterator it(dir, ec), end; !ec && it != end; it.increment(ec)) {
    if (!is_hidden(it->path())) entries.push_back(it->path());
  }
  if (ec) throw IoError(fmt::format("{}: cannot list folder: {}", dir.string(), ec.message()));
  std::sort(entries.begin(), entries.end());
  return entries;
}

// Number of frames of one camera in one take, after checking they run 0..n-1 without gaps.
int count_frames(const Session& session, const std::string& take, const std::string& camera) {
  const fs::path dir = session.capture_dir() / take / camera;
  if (!fs::is_directory(dir)) {
    throw InputError(fmt::format("take '{}': calibrated camera '{}' has no folder {}", take,
                                 camera, dir.string()));
  }
  std::vector<int> frames;
  for (const fs::path& p : sorted_entries(dir)) {
    if (auto f = frame_number(p); f && fs::is_regular_file(p)) frames.push_back(*f);
  }
  if (frames.empty()) {
    throw InputError(fmt::format("take '{}': camera '{}' has no frames (000000.png, ...) in {}",
                                 take, camera, dir.string()));
  }
  std::sort(frames.begin(), frames.end());
  for (int i = 0; i < static_cast<int>(frames.size()); ++i) {
    if (frames[i] != i) {
      throw InputError(fmt::format(
          "take '{}': camera '{}' is missing frame {} ({}) but has frame {}", take, camera,
          frame_name(i), session.capture_image(take, camera, i).string(), frames[i]));
    }
  }
  return static_cast<int>(frames.size());
}

TakeCapture scan_take(const Session& session, const std::string& take,
                      const std::vector<Camera>& calibration) {
  TakeCapture result;
  result.name = take;
  const Camera* first = nullptr;
  for (const Camera& camera : calibration) {
    const int count = count_frames(session, take, camera.name);
    if (!first) {
      first = &camera;
      result.frame_count = count;
    } else if (count != result.frame_count) {
      throw InputError(fmt::format(
          "take '{}': camera '{}' has {} frames but camera '{}' has {}; every camera must "
          "record every frame",
          take, camera.name, count, first->name, result.frame_count));
    }
  }
  for (const fs::path& p : sorted_entries(session.capture_dir() / take)) {
    const std::string folder = p.filename().string();
    const bool calibrated = std::any_of(calibration.begin(), calibration.end(),
                                        [&](const Camera& c) { return c.name == folder; });
    if (!calibrated && fs::is_directory(p)) result.uncalibrated_folders.push_back(folder);
  }
  return result;
}

}  // namespace

const TakeCapture& CaptureIndex::take(const std::string& name) const {
  for (const TakeCapture& t : takes) {
    if (t.name == name) return t;
  }
  std::string known;
  for (const TakeCapture& t : takes) known += (known.empty() ? "" : ", ") + t.name;
  throw InputError(fmt::format("take '{}' is not in the capture (takes: {})", name,
                               known.empty() ? "none" : known));
}

CaptureIndex scan_capture(const Session& session, const std::vector<Camera>& calibration) {
  const fs::path root = session.capture_dir();
  if (calibration.empty()) throw InputError("scan_capture: the calibration has no cameras");
  if (!fs::is_directory(root)) {
    throw InputError(fmt::format("{}: capture folder does not exist", root.string()));
  }
  CaptureIndex index;
  for (const fs::path& p : sorted_entries(root)) {
    if (fs::is_directory(p)) index.takes.push_back(scan_take(session, p.filename().string(), calibration));
  }
  if (index.takes.empty()) {
    throw InputError(fmt::format("{}: no takes (expected capture/<take>/<camera>/000000.png)",
                                 root.string()));
  }
  return index;
}

cv::Mat read_capture_image(const Session& session, const Camera& camera, const std::string& take,
                           int frame) {
  const fs::path path = session.capture_image(take, camera.name, frame);
  const std::string where =
      fmt::format("take '{}', camera '{}', frame {}", take, camera.name, frame_name(frame));
  if (!fs::exists(path)) {
    throw InputError(fmt::format("{}: frame file does not exist ({})", path.string(), where));
  }
  cv::Mat image;
  try {
    image = read_image(path, cv::IMREAD_COLOR);
  } catch (const InputError& e) {
    throw InputError(fmt::format("{} ({})", e.what(), where));
  } catch (const IoError& e) {
    throw IoError(fmt::format("{} ({})", e.what(), where));
  }
  const Intrinsics& in = camera.intrinsics;
  if (image.cols != in.width || image.rows != in.height) {
    throw InputError(fmt::format("{}: image is {}x{} but the calibration of camera '{}' is {}x{} ({})",
                                 path.string(), image.cols, image.rows, camera.name, in.width,
                                 in.height, where));
  }
  return image;
}

}  // namespace fourd
