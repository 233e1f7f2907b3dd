#pragma once
// Pictures of meshes for the reports (the motion spaces' Figure 4, validation's transition
// filmstrip): a grid of flat-shaded panels, each a mesh with per-vertex colours (e.g. an error
// heat map), drawn with the painter's algorithm in an orthographic view from the front right,
// all panels at one common scale.
#include <Eigen/Core>
#include <opencv2/core.hpp>
#include <span>
#include <string>
#include <vector>

#include "pipeline/core/mesh.h"

namespace fourd {

struct FigurePanel {
  Eigen::Matrix3Xd positions;     // 3 x #V, z up, facing +x
  std::vector<cv::Vec3b> colors;  // #V BGR
};

struct FigureLayout {
  int panel_width = 220;   // [px]
  int panel_height = 300;  // [px]
  std::vector<std::string> row_labels;
  std::vector<std::string> column_labels;
  std::string title;
  // false: each mesh stands on the panel's floor line (its own lowest point); true: one height
  // for every panel (z = the lowest point of all), so a lift off the ground shows.
  bool common_floor = false;
  // Colour bar under the grid: from 0 to `bar_max`, labelled `bar_label` (none if empty).
  std::string bar_label;
  double bar_max = 0;
};

// BGR heat-map colour of value / max (clamped), blue (0) to red (max).
cv::Vec3b heat_color(double value, double max);

// Panels in row-major order, rows x columns of the layout's labels; a panel without vertices
// stays blank.
cv::Mat render_figure(std::span<const FigurePanel> panels, std::span<const Tri> triangles,
                      const FigureLayout& layout);

}  // namespace fourd
