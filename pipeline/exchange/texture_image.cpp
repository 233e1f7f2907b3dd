#include "pipeline/exchange/texture_image.h"

#include <OpenImageIO/imageio.h>
#include <fmt/format.h>

#include <opencv2/imgproc.hpp>

#include "pipeline/core/error.h"
#include "pipeline/core/files.h"

namespace fourd {

std::string texture_extension(const std::string& format, const std::string& field) {
  if (format == "png") return ".png";
  if (format == "exr") return ".exr";
  throw ConfigError(fmt::format("{} = '{}': expected 'png' or 'exr'", field, format));
}

void write_texture(const std::filesystem::path& path, const cv::Mat& image) {
  const std::string ext = path.extension().string();
  const bool exr = ext == ".exr";
  if (!exr && ext != ".png") {
    throw IoError(fmt::format("{}: textures are written as .png or .exr", path.string()));
  }
  if (image.empty()) throw IoError(fmt::format("{}: empty image", path.string()));
  cv::Mat rgb;
  if (image.channels() == 3) {
    cv::cvtColor(image, rgb, cv::COLOR_BGR2RGB);
  } else {
    rgb = image;
  }
  const OIIO::TypeDesc data_type = rgb.depth() == CV_32F ? OIIO::TypeDesc::FLOAT : OIIO::TypeDesc::UINT8;
  OIIO::ImageSpec spec(rgb.cols, rgb.rows, rgb.channels(),
                       exr ? OIIO::TypeDesc::HALF : OIIO::TypeDesc::UINT8);
  if (exr) {
    spec.attribute("compression", "zip");
  } else {
    spec.attribute("png:compressionLevel", 1);  // fast: textures are rewritten every run
  }
  ensure_directory(path.parent_path());
  const std::filesystem::path temp = temp_path_for(path);
  auto out = OIIO::ImageOutput::create(exr ? "openexr" : "png");
  if (!out) {
    throw IoError(fmt::format("{}: OpenImageIO has no writer: {}", path.string(), OIIO::geterror()));
  }
  if (!rgb.isContinuous()) rgb = rgb.clone();
  const bool ok = out->open(temp.string(), spec) && out->write_image(data_type, rgb.data) &&
                  out->close();
  if (!ok) {
    const std::string message = out->geterror();
    std::error_code ec;
    std::filesystem::remove(temp, ec);
    throw IoError(fmt::format("{}: cannot write: {}", path.string(), message));
  }
  commit_temp_file(temp, path);
}

cv::Mat read_texture(const std::filesystem::path& path) {
  auto in = OIIO::ImageInput::open(path.string());
  if (!in) {
    throw IoError(fmt::format("{}: cannot read the texture: {}", path.string(), OIIO::geterror()));
  }
  const OIIO::ImageSpec& spec = in->spec();
  if (spec.nchannels < 3) {
    throw IoError(fmt::format("{}: {} channels, a texture needs RGB", path.string(), spec.nchannels));
  }
  cv::Mat all(spec.height, spec.width, CV_32FC(spec.nchannels));
  if (!in->read_image(0, 0, 0, spec.nchannels, OIIO::TypeDesc::FLOAT, all.data)) {
    throw IoError(fmt::format("{}: cannot read the texture: {}", path.string(), in->geterror()));
  }
  cv::Mat bgr(spec.height, spec.width, CV_32FC3);
  const int from_to[] = {0, 2, 1, 1, 2, 0};
  cv::mixChannels(&all, 1, &bgr, 1, from_to, 3);
  return bgr;
}

}  // namespace fourd
