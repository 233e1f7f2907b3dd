#include "stages/common/figure.h"

#include <fmt/format.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <numbers>
#include <numeric>
#include <opencv2/imgproc.hpp>

namespace fourd {

namespace {

constexpr int kSupersample = 2;   // panels are drawn at twice the size, then shrunk (antialiasing)
constexpr int kLabelWidth = 150;  // [px] left of the grid
constexpr int kHeaderHeight = 56;
constexpr int kBarHeight = 60;

// View from the front right: screen x to the character's left, screen y down, depth towards
// the viewer.
struct View {
  Eigen::Vector3d right, up, towards;
  View() {
    const double a = -55 * std::numbers::pi / 180;
    towards = Eigen::Vector3d(std::cos(a), std::sin(a), 0.25).normalized();
    right = Eigen::Vector3d::UnitZ().cross(towards).normalized();
    up = towards.cross(right);
  }
};

void draw_panel(const FigurePanel& panel, std::span<const Tri> triangles, const View& view,
                const Eigen::Vector2d& lo, double scale, cv::Mat& canvas) {
  const Eigen::Index nv = panel.positions.cols();
  std::vector<cv::Point> screen(nv);
  for (Eigen::Index v = 0; v < nv; ++v) {
    const Eigen::Vector3d p = panel.positions.col(v);
    const double sx = (p.dot(view.right) - lo.x()) * scale;
    const double sy = canvas.rows - (p.dot(view.up) - lo.y()) * scale;
    screen[v] = cv::Point(static_cast<int>(std::lround(sx)), static_cast<int>(std::lround(sy)));
  }
  std::vector<double> depth(triangles.size());
  for (std::size_t f = 0; f < triangles.size(); ++f) {
    const Tri& t = triangles[f];
    depth[f] = (panel.positions.col(t[0]) + panel.positions.col(t[1]) + panel.positions.col(t[2]))
                   .dot(view.towards);
  }
  std::vector<std::size_t> order(triangles.size());
  std::iota(order.begin(), order.end(), 0);
  std::sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) {
    return depth[a] < depth[b];  // far first
  });
  for (std::size_t f : order) {
    const Tri& t = triangles[f];
    const Eigen::Vector3d a = panel.positions.col(t[0]), b = panel.positions.col(t[1]),
                          c = panel.positions.col(t[2]);
    const Eigen::Vector3d n = (b - a).cross(c - a);
    const double len = n.norm();
    if (!(len > 0)) continue;
    const double facing = n.dot(view.towards) / len;
    if (facing <= 0) continue;  // back face
    const double shade = 0.35 + 0.65 * facing;
    cv::Vec3d color(0, 0, 0);
    for (int k = 0; k < 3; ++k) color += cv::Vec3d(panel.colors[t[k]]) / 3.0;
    const cv::Point pts[3] = {screen[t[0]], screen[t[1]], screen[t[2]]};
    cv::fillConvexPoly(canvas, pts, 3,
                       cv::Scalar(color[0] * shade, color[1] * shade, color[2] * shade),
                       cv::LINE_8);
  }
}

}  // namespace

cv::Vec3b heat_color(double value, double max) {
  static const cv::Mat lut = [] {
    cv::Mat ramp(1, 256, CV_8UC1);
    for (int i = 0; i < 256; ++i) ramp.at<std::uint8_t>(0, i) = static_cast<std::uint8_t>(i);
    cv::Mat colors;
    cv::applyColorMap(ramp, colors, cv::COLORMAP_TURBO);
    return colors;
  }();
  const double f = max > 0 ? std::clamp(value / max, 0.0, 1.0) : 0.0;
  return lut.at<cv::Vec3b>(0, static_cast<int>(std::lround(255 * f)));
}

cv::Mat render_figure(std::span<const FigurePanel> panels, std::span<const Tri> triangles,
                      const FigureLayout& layout) {
  const int rows = static_cast<int>(layout.row_labels.size());
  const int cols = static_cast<int>(layout.column_labels.size());
  const int pw = layout.panel_width, ph = layout.panel_height;
  const bool bar = !layout.bar_label.empty() && layout.bar_max > 0;
  cv::Mat image(kHeaderHeight + rows * ph + (bar ? kBarHeight : 0), kLabelWidth + cols * pw,
                CV_8UC3, cv::Scalar(255, 255, 255));
  // One scale for every panel: the largest extent of any mesh in the view.
  const View view;
  Eigen::Vector2d extent(0, 0);
  double floor = 1e300;  // lowest screen height of all panels
  std::vector<Eigen::Vector2d> lows, widths;
  for (const FigurePanel& p : panels) {
    Eigen::Vector2d lo(1e300, 1e300), hi(-1e300, -1e300);
    if (p.positions.cols() == 0) lo = hi = Eigen::Vector2d::Zero();
    for (Eigen::Index v = 0; v < p.positions.cols(); ++v) {
      const Eigen::Vector2d s(p.positions.col(v).dot(view.right), p.positions.col(v).dot(view.up));
      lo = lo.cwiseMin(s);
      hi = hi.cwiseMax(s);
    }
    extent = extent.cwiseMax(hi - lo);
    if (p.positions.cols() > 0) floor = std::min(floor, lo.y());
    lows.push_back(lo);
    widths.push_back(hi - lo);
  }
  if (layout.common_floor) {
    // Every panel's height range starts at the common floor.
    for (std::size_t i = 0; i < lows.size(); ++i) {
      extent.y() = std::max(extent.y(), lows[i].y() + widths[i].y() - floor);
    }
  }
  const double margin = 0.06;
  const double scale = kSupersample * std::min(pw / (extent.x() * (1 + 2 * margin)),
                                               ph / (extent.y() * (1 + 2 * margin)));
  for (int r = 0; r < rows; ++r) {
    for (int c = 0; c < cols; ++c) {
      const std::size_t i = static_cast<std::size_t>(r) * cols + c;
      if (i >= panels.size()) break;
      if (panels[i].positions.cols() == 0) continue;
      cv::Mat big(ph * kSupersample, pw * kSupersample, CV_8UC3, cv::Scalar(255, 255, 255));
      // Centre horizontally, stand on a common floor line.
      Eigen::Vector2d lo = lows[i];
      lo.x() -= 0.5 * (big.cols / scale - widths[i].x());
      if (layout.common_floor) lo.y() = floor;
      lo.y() -= margin * extent.y();
      draw_panel(panels[i], triangles, view, lo, scale, big);
      cv::Mat small;
      cv::resize(big, small, cv::Size(pw, ph), 0, 0, cv::INTER_AREA);
      small.copyTo(image(cv::Rect(kLabelWidth + c * pw, kHeaderHeight + r * ph, pw, ph)));
    }
  }
  const int font = cv::FONT_HERSHEY_SIMPLEX;
  const cv::Scalar ink(30, 30, 30);
  cv::putText(image, layout.title, cv::Point(8, 22), font, 0.6, ink, 1, cv::LINE_AA);
  for (int c = 0; c < cols; ++c) {
    cv::putText(image, layout.column_labels[c], cv::Point(kLabelWidth + c * pw + 10, 48), font, 0.5,
                ink, 1, cv::LINE_AA);
  }
  for (int r = 0; r < rows; ++r) {
    cv::putText(image, layout.row_labels[r], cv::Point(6, kHeaderHeight + r * ph + ph / 2), font,
                0.45, ink, 1, cv::LINE_AA);
  }
  if (bar) {
    const int y = kHeaderHeight + rows * ph + 12, x0 = kLabelWidth, width = cols * pw - 120;
    for (int x = 0; x < width; ++x) {
      cv::line(image, cv::Point(x0 + x, y), cv::Point(x0 + x, y + 16),
               cv::Scalar(heat_color(x, width - 1)), 1);
    }
    cv::putText(image, "0", cv::Point(x0 - 14, y + 14), font, 0.45, ink, 1, cv::LINE_AA);
    cv::putText(image, layout.bar_label, cv::Point(x0 + width + 6, y + 14), font, 0.45, ink, 1,
                cv::LINE_AA);
  }
  return image;
}

}  // namespace fourd
