#pragma once
// Texture images through OpenImageIO: 8-bit PNG (the default) or half-float OpenEXR, written
// atomically (temp file + rename), read back as float BGR.
#include <filesystem>
#include <opencv2/core.hpp>
#include <string>

namespace fourd {

// "png" or "exr"; ConfigError naming `field` otherwise.
std::string texture_extension(const std::string& format, const std::string& field);

// Writes a BGR image (CV_8UC3, CV_32FC3 in [0, 1], or CV_8UC1) to `path`; the format follows
// the extension (.png: 8 bits, fast zlib level; .exr: half float, zip). Throws IoError naming
// the file when it cannot be written.
void write_texture(const std::filesystem::path& path, const cv::Mat& image);

// Reads a texture written by write_texture (or any RGB/RGBA image OpenImageIO reads) as CV_32FC3
// BGR in [0, 1]. Throws IoError naming the file when it cannot be read.
cv::Mat read_texture(const std::filesystem::path& path);

}  // namespace fourd
