#pragma once
// Small helpers the validators share: which takes and frames exist, which to sample,
// percentiles, picture panels.
#include <filesystem>
#include <opencv2/core.hpp>
#include <string>
#include <vector>

#include "pipeline/core/statistics.h"  // percentile

namespace fourd::validate {

// Names of the sub-folders of `dir` (takes, cameras), sorted, hidden ones left out; empty when
// the folder does not exist.
std::vector<std::string> subfolders(const std::filesystem::path& dir);

// Frames 0..n-1 stored as <NNNNNN><ext> in `dir` (".png", ".ply"): n is the largest index + 1;
// 0 when the folder does not exist.
int frame_count(const std::filesystem::path& dir, const std::string& ext);

// `count` frames spread evenly over 0 .. frames-1 (both ends included when count >= 2; the
// middle one when count is 1; every frame when count >= frames).
std::vector<int> sample_frames(int frames, int count);

// One image panel scaled to `width` (`interpolation` as cv::resize's), grey turned to BGR,
// with a label in the top-left corner.
cv::Mat panel(const cv::Mat& image, int width, int interpolation, const std::string& label);

}  // namespace fourd::validate
