#pragma once
// Image files through OpenCV, with the project's error and atomic-write conventions.
#include <filesystem>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <vector>

namespace fourd {

// Writes `image` with cv::imwrite (format from the extension of `path`, e.g. ".png") to a temp
// file beside `path` and renames it onto `path`, so readers never see half an image. Creates
// the parent folder. `params` are cv::imwrite's (e.g. {cv::IMWRITE_PNG_COMPRESSION, 1}).
// Throws IoError naming the file when the image is empty or cannot be encoded or written.
void write_image_atomic(const std::filesystem::path& path, const cv::Mat& image,
                        const std::vector<int>& params = {});

// Reads and decodes an image file with cv::imdecode (`flags` as cv::imread's; the default gives
// 8-bit BGR). Throws IoError naming the file when it does not exist or cannot be read, and
// InputError when its content is not a decodable image (corrupt or truncated file).
cv::Mat read_image(const std::filesystem::path& path, int flags = cv::IMREAD_COLOR);

}  // namespace fourd
