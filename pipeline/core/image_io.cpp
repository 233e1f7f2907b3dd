#include "pipeline/core/image_io.h"

#include <fmt/format.h>

#include "pipeline/core/error.h"
#include "pipeline/core/files.h"

namespace fourd {

void write_image_atomic(const std::filesystem::path& path, const cv::Mat& image,
                        const std::vector<int>& params) {
  if (image.empty()) throw IoError(fmt::format("{}: refusing to write an empty image", path.string()));
  if (!path.parent_path().empty()) ensure_directory(path.parent_path());
  const std::filesystem::path temp = temp_path_for(path);
  bool written = false;
  std::string reason = "the encoder failed";
  try {
    written = cv::imwrite(temp.string(), image, params);
  } catch (const cv::Exception& e) {
    reason = e.what();  // unsupported depth/channels for the format, unknown extension...
  }
  if (!written) {
    std::error_code ec;
    std::filesystem::remove(temp, ec);
    throw IoError(fmt::format("cannot write image {} ({}x{}, type {}): {}", path.string(),
                              image.cols, image.rows, cv::typeToString(image.type()), reason));
  }
  commit_temp_file(temp, path);
}

cv::Mat read_image(const std::filesystem::path& path, int flags) {
  // Reading the bytes ourselves tells a missing or unreadable file (IoError) from a corrupt
  // one (InputError), which cv::imread reports the same way.
  const std::string bytes = read_file(path);
  cv::Mat image;
  try {
    image = cv::imdecode(cv::Mat(1, static_cast<int>(bytes.size()), CV_8UC1,
                                 const_cast<char*>(bytes.data())),
                         flags);
  } catch (const cv::Exception& e) {
    throw InputError(fmt::format("{}: cannot decode image: {}", path.string(), e.what()));
  }
  if (image.empty()) {
    throw InputError(fmt::format("{}: not a readable image (corrupt or truncated file?)",
                                 path.string()));
  }
  return image;
}

}  // namespace fourd
