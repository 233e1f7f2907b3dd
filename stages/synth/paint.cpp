#include "stages/synth/paint.h"

#include <tbb/parallel_for.h>

namespace fourd::synth::detail {

cv::Mat paint_image(int size, const std::function<Rgb(double u, double v)>& colour) {
  cv::Mat image(size, size, CV_8UC3);
  tbb::parallel_for(0, size, [&](int row) {
    auto* px = image.ptr<cv::Vec3b>(row);
    const double v = 1.0 - (row + 0.5) / size;
    for (int col = 0; col < size; ++col) {
      const double u = (col + 0.5) / size;
      const Rgb c = colour(u, v);
      px[col] = cv::Vec3b(static_cast<std::uint8_t>(std::lround(255 * c.z())),
                          static_cast<std::uint8_t>(std::lround(255 * c.y())),
                          static_cast<std::uint8_t>(std::lround(255 * c.x())));
    }
  });
  return image;
}

}  // namespace fourd::synth::detail
