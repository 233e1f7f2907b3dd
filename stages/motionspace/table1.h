#pragma once
// The paper's Table 1 on our data: on the blend of the two takes whose shapes differ most in
// rotation, the largest vertex distance from the non-linear blend (in % of the character's
// height) of the linear blend, the hybrid blend with 1 reference (w = 0.5: one quadratic / arc
// cell) and with 3 references (w = 0.25, 0.5, 0.75: cells [0, 0.5] and [0.5, 1]; see
// runtime/blend.h and add_line_references), over every sample of the motion and test weights evenly
// inside (0, 1); and the time per frame of each method. Also the data of the paper's Figure 4:
// the blend at five weights with per-vertex error maps, at the sample where linear blending
// errs most.
#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>
#include <string>
#include <vector>

#include "pipeline/exchange/warped_class.h"

namespace fourd {

// The pair of takes of a class whose shapes differ most in rotation: per triangle, the angle of
// the rotation between the two takes' deformation gradients, averaged over the triangles and
// the samples.
struct RotationScore {
  int a = 0, b = 1;
  double mean_rotation_deg = 0;
};
RotationScore most_rotated_pair(const WarpedClass& warped);

struct Table1Row {
  std::string method;
  int references = 0;           // hybrid references (0 for linear and non-linear)
  double max_error_m = 0;
  double max_error_pct = 0;     // of the character height
  double seconds_per_frame = 0; // one core
};

struct Table1 {
  std::string motion_class, take_a, take_b;
  double rotation_deg = 0;
  double character_height = 0;
  int samples = 0;
  std::vector<double> test_weights;  // weight of take b
  Table1Row linear, hybrid1, hybrid3, nonlinear;
  // Figure 4 (weights 0, 0.25, 0.5, 0.75, 1 of take b, at sample figure_sample).
  int figure_sample = 0;
  cv::Mat figure;  // BGR
};

// `test_weights` weights evenly inside (0, 1). Runs the non-linear blends on all cores; the
// times are measured on one.
Table1 evaluate_table1(const WarpedClass& warped, int a, int b, int test_weights = 19);

nlohmann::json table1_json(const Table1& table);

}  // namespace fourd
