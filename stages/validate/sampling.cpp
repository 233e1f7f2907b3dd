#include "stages/validate/sampling.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <opencv2/imgproc.hpp>

namespace fourd::validate {

namespace fs = std::filesystem;

std::vector<std::string> subfolders(const fs::path& dir) {
  std::vector<std::string> out;
  std::error_code ec;
  if (!fs::is_directory(dir, ec)) return out;
  for (const auto& e : fs::directory_iterator(dir)) {
    const std::string name = e.path().filename().string();
    if (e.is_directory() && !name.empty() && name.front() != '.') out.push_back(name);
  }
  std::sort(out.begin(), out.end());
  return out;
}

int frame_count(const fs::path& dir, const std::string& ext) {
  int n = 0;
  std::error_code ec;
  if (!fs::is_directory(dir, ec)) return 0;
  for (const auto& e : fs::directory_iterator(dir)) {
    const std::string stem = e.path().stem().string();
    if (e.path().extension() != ext || stem.size() != 6 ||
        !std::all_of(stem.begin(), stem.end(), [](unsigned char c) { return std::isdigit(c); })) {
      continue;
    }
    n = std::max(n, std::stoi(stem) + 1);
  }
  return n;
}

std::vector<int> sample_frames(int frames, int count) {
  std::vector<int> out;
  if (count >= frames) {
    for (int f = 0; f < frames; ++f) out.push_back(f);
    return out;
  }
  for (int i = 0; i < count; ++i) {
    int f = count == 1 ? frames / 2
                       : static_cast<int>(std::lround(double(i) * (frames - 1) / (count - 1)));
    if (out.empty() || out.back() != f) out.push_back(f);
  }
  return out;
}

cv::Mat panel(const cv::Mat& image, int width, int interpolation, const std::string& label) {
  double scale = double(width) / image.cols;
  cv::Mat out;
  cv::resize(image, out, {width, std::max(1, static_cast<int>(std::lround(image.rows * scale)))}, 0,
             0, interpolation);
  if (out.channels() == 1) cv::cvtColor(out, out, cv::COLOR_GRAY2BGR);
  double font = std::max(0.3, 0.5 * width / 480.0);  // readable, and fits narrow panels
  cv::Point at{6, static_cast<int>(6 + 22 * font)};
  cv::putText(out, label, at, cv::FONT_HERSHEY_SIMPLEX, font, {0, 0, 0}, 3, cv::LINE_AA);
  cv::putText(out, label, at, cv::FONT_HERSHEY_SIMPLEX, font, {255, 255, 255}, 1, cv::LINE_AA);
  return out;
}

}  // namespace fourd::validate
