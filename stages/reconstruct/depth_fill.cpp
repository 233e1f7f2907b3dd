#include "stages/reconstruct/depth_fill.h"

#include <algorithm>
#include <cmath>
#include <opencv2/imgproc.hpp>
#include <vector>

namespace fourd::reconstruct {

namespace {

constexpr int kMaxIterations = 3000;
constexpr double kConverged = 1e-6;  // largest change of a relaxation sweep [m]
constexpr double kOverRelaxation = 1.8;
constexpr int kMedianRadius = 3;     // window of the border's median depths [px]

}  // namespace

std::size_t fill_depth_holes(const cv::Mat& hull_depth, DepthMap& map, double front_margin,
                             double search_depth, const DepthFillOptions& options) {
  map.filled = cv::Mat::zeros(map.depth.size(), CV_8U);
  if (!options.enabled) return 0;
  const cv::Mat inside_hull = hull_depth > 0;
  const cv::Mat holes = inside_hull & (map.depth <= 0);
  cv::Mat labels, stats, centroids;
  const int count = cv::connectedComponentsWithStats(holes, labels, stats, centroids, 8, CV_32S);
  const cv::Rect image(0, 0, map.depth.cols, map.depth.rows);
  std::size_t filled = 0;
  for (int k = 1; k < count; ++k) {
    if (stats.at<int>(k, cv::CC_STAT_AREA) > options.max_pixels) continue;
    const cv::Rect box = cv::Rect(stats.at<int>(k, cv::CC_STAT_LEFT) - 1,
                                  stats.at<int>(k, cv::CC_STAT_TOP) - 1,
                                  stats.at<int>(k, cv::CC_STAT_WIDTH) + 2,
                                  stats.at<int>(k, cv::CC_STAT_HEIGHT) + 2) &
                         image;
    const cv::Mat hole = labels(box) == k;
    const cv::Mat depth = map.depth(box);
    const cv::Mat hull = hull_depth(box);
    const cv::Mat matched = depth > 0;
    // The hole's border: the pixels next to it, matched or outside the silhouette (no other
    // hole touches it: the components are 8-connected).
    cv::Mat grown;
    cv::dilate(hole, grown, cv::Mat::ones(3, 3, CV_8U));
    const cv::Mat border = grown & ~hole;
    const int border_pixels = cv::countNonZero(border);
    if (border_pixels == 0 ||
        cv::countNonZero(border & matched) < options.min_enclosed * border_pixels) {
      continue;
    }
    // The depth behind the hull, harmonic inside the hole, fixed on its border: 0 on the
    // outline (where the hull touches the surface it was carved around) and, next to matched
    // pixels, the median of the matched depths around them (a lone wrong match next to the
    // hole would otherwise spread into all of it).
    std::vector<cv::Point> inside;
    cv::findNonZero(hole, inside);
    cv::Mat offset = cv::Mat::zeros(box.size(), CV_64F);
    std::vector<double> around;
    for (int y = 0; y < box.height; ++y) {
      for (int x = 0; x < box.width; ++x) {
        if (!border.at<std::uint8_t>(y, x) || !matched.at<std::uint8_t>(y, x)) continue;
        const cv::Rect window = cv::Rect(box.x + x - kMedianRadius, box.y + y - kMedianRadius,
                                         2 * kMedianRadius + 1, 2 * kMedianRadius + 1) &
                                image;
        around.clear();
        for (int v = window.y; v < window.y + window.height; ++v) {
          for (int u = window.x; u < window.x + window.width; ++u) {
            const float d = map.depth.at<float>(v, u);
            if (d > 0) around.push_back(d - hull_depth.at<float>(v, u));
          }
        }
        std::nth_element(around.begin(), around.begin() + around.size() / 2, around.end());
        offset.at<double>(y, x) = around[around.size() / 2];
      }
    }
    const int dx[4] = {1, -1, 0, 0}, dy[4] = {0, 0, 1, -1};
    for (int it = 0; it < kMaxIterations; ++it) {
      double change = 0;
      for (const cv::Point& p : inside) {
        double sum = 0;
        int n = 0;
        for (int d = 0; d < 4; ++d) {
          const int x = p.x + dx[d], y = p.y + dy[d];
          if (x < 0 || y < 0 || x >= box.width || y >= box.height) continue;
          sum += offset.at<double>(y, x);
          ++n;
        }
        double& o = offset.at<double>(p);
        const double step = sum / n - o;
        change = std::max(change, std::abs(step));
        o += kOverRelaxation * step;
      }
      if (change < kConverged) break;
    }
    cv::Mat target = map.depth(box);
    cv::Mat mark = map.filled(box);
    for (const cv::Point& p : inside) {
      const double o = std::clamp(offset.at<double>(p), -front_margin, search_depth);
      target.at<float>(p) = static_cast<float>(hull.at<float>(p) + o);
      mark.at<std::uint8_t>(p) = 1;
    }
    filled += inside.size();
  }
  return filled;
}

}  // namespace fourd::reconstruct
