#include "stages/motionspace/table1.h"

#include <fmt/format.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <numbers>

#include "runtime/blend.h"
#include "stages/common/figure.h"
#include "stages/motionspace/hybrid_build.h"
#include "stages/motionspace/nonlinear_blend.h"

namespace fourd {

namespace {


BlendSpace pair_space(const WarpedClass& c, int a, int b) {
  BlendSpace space = make_blend_space(2, c.num_vertices, c.num_samples);
  const int takes[2] = {a, b};
  for (int k = 0; k < 2; ++k) {
    for (int i = 0; i < c.num_samples; ++i) {
      const Vec3f* p = c.takes[takes[k]].shapes.data() + static_cast<std::size_t>(i) * c.num_vertices;
      set_frame(&space, k, i, std::span<const Vec3f>(p, c.num_vertices));
    }
  }
  return space;
}

double t_of(int sample, int samples) {
  return samples > 1 ? static_cast<double>(sample) / (samples - 1) : 0.0;
}

// Per-vertex distances between a runtime blend and a reference [m].
std::vector<float> vertex_errors(const BlendedFrame& blend, const Eigen::Matrix3Xd& x) {
  std::vector<float> e(blend.num_vertices);
  for (int v = 0; v < blend.num_vertices; ++v) {
    e[v] = static_cast<float>((blend.position(v).cast<double>() - x.col(v)).norm());
  }
  return e;
}

float max_of(const std::vector<float>& e) { return *std::max_element(e.begin(), e.end()); }

Eigen::Matrix3Xd to_matrix(const BlendedFrame& blend) {
  Eigen::Matrix3Xd x(3, blend.num_vertices);
  for (int v = 0; v < blend.num_vertices; ++v) x.col(v) = blend.position(v).cast<double>();
  return x;
}

// Mean seconds per call of a runtime blend over quasi-random (t, w).
template <class F>
double time_per_call(F&& blend) {
  const int calls = 4000;
  double t = 0, s = 0;
  for (int i = 0; i < calls / 4; ++i) blend(0.5, 0.5f);  // warm up caches and clocks
  const auto start = std::chrono::steady_clock::now();
  for (int i = 0; i < calls; ++i) {
    t = std::fmod(t + 0.618034, 1.0);
    s = std::fmod(s + 0.414214, 1.0);
    blend(t, static_cast<float>(s));
  }
  const std::chrono::duration<double> elapsed = std::chrono::steady_clock::now() - start;
  return elapsed.count() / calls;
}

}  // namespace

RotationScore most_rotated_pair(const WarpedClass& c) {
  NonlinearBlendData data;
  nonlinear_blend_precompute(c.template_positions, c.triangles, &data);
  RotationScore best;
  best.mean_rotation_deg = -1;
  const int n = static_cast<int>(c.takes.size());
  for (int a = 0; a < n; ++a) {
    for (int b = a + 1; b < n; ++b) {
      std::vector<double> per_sample(c.num_samples, 0.0);
      tbb::parallel_for(0, c.num_samples, [&](int i) {
        const std::vector<Eigen::Matrix3Xd> inputs{c.shape(a, i), c.shape(b, i)};
        NonlinearBlendInputs prepared;
        nonlinear_blend_prepare(data, inputs, &prepared);
        double sum = 0;
        const std::size_t nf = data.triangles.size();
        for (std::size_t f = 0; f < nf; ++f) sum += prepared.log_rotations[f * 2 + 1].norm();
        per_sample[i] = sum / static_cast<double>(nf);
      });
      double mean = 0;
      for (double x : per_sample) mean += x / c.num_samples;
      mean *= 180 / std::numbers::pi;
      if (mean > best.mean_rotation_deg) best = {a, b, mean};
    }
  }
  return best;
}

Table1 evaluate_table1(const WarpedClass& c, int a, int b, int test_weights) {
  Table1 table;
  table.motion_class = c.name;
  table.take_a = c.takes[a].name;
  table.take_b = c.takes[b].name;
  table.character_height = c.character_height;
  table.samples = c.num_samples;
  for (int j = 1; j <= test_weights; ++j) table.test_weights.push_back(j / (test_weights + 1.0));

  const BlendSpace linear_space = pair_space(c, a, b);
  BlendSpace hybrid1 = linear_space, hybrid3 = linear_space;
  add_line_references(c.template_positions, c.triangles, std::array<double, 1>{0.5}, &hybrid1);
  add_line_references(c.template_positions, c.triangles, std::array<double, 3>{0.25, 0.5, 0.75},
                      &hybrid3);
  NonlinearBlendData data;
  nonlinear_blend_precompute(c.template_positions, c.triangles, &data);

  // Errors at every sample and test weight (samples in parallel, each writes its own row).
  const int f_count = c.num_samples;
  std::vector<std::array<double, 3>> worst(f_count, {0, 0, 0});
  tbb::parallel_for(0, f_count, [&](int i) {
    const std::vector<Eigen::Matrix3Xd> inputs{c.shape(a, i), c.shape(b, i)};
    NonlinearBlendInputs prepared;
    nonlinear_blend_prepare(data, inputs, &prepared);
    BlendedFrame out = make_blended_frame(linear_space);
    Eigen::Matrix3Xd x;
    const double t = t_of(i, f_count);
    for (double s : table.test_weights) {
      nonlinear_blend_solve(data, prepared, std::array<double, 2>{1 - s, s}, &x);
      const std::array<float, 2> w{static_cast<float>(1 - s), static_cast<float>(s)};
      blend_linear(linear_space, t, w, &out);
      worst[i][0] = std::max<double>(worst[i][0], max_of(vertex_errors(out, x)));
      blend_hybrid(hybrid1, t, w, &out);
      worst[i][1] = std::max<double>(worst[i][1], max_of(vertex_errors(out, x)));
      blend_hybrid(hybrid3, t, w, &out);
      worst[i][2] = std::max<double>(worst[i][2], max_of(vertex_errors(out, x)));
    }
  });
  Table1Row* rows[3] = {&table.linear, &table.hybrid1, &table.hybrid3};
  for (int i = 0; i < f_count; ++i) {
    for (int m = 0; m < 3; ++m) rows[m]->max_error_m = std::max(rows[m]->max_error_m, worst[i][m]);
    if (worst[i][0] > worst[table.figure_sample][0]) table.figure_sample = i;
  }
  table.linear.method = "linear";
  table.hybrid1.method = "hybrid, 1 reference";
  table.hybrid1.references = 1;
  table.hybrid3.method = "hybrid, 3 references";
  table.hybrid3.references = 3;
  table.nonlinear.method = "non-linear";
  for (Table1Row* r : rows) r->max_error_pct = 100 * r->max_error_m / c.character_height;

  // Times on one core.
  {
    BlendedFrame out = make_blended_frame(linear_space);
    auto runtime = [&](const BlendSpace& space, bool hybrid) {
      return time_per_call([&](double t, float s) {
        const std::array<float, 2> w{1 - s, s};
        hybrid ? blend_hybrid(space, t, w, &out) : blend_linear(space, t, w, &out);
      });
    };
    table.linear.seconds_per_frame = runtime(linear_space, false);
    table.hybrid1.seconds_per_frame = runtime(hybrid1, true);
    table.hybrid3.seconds_per_frame = runtime(hybrid3, true);
    // Non-linear: decompose both inputs and solve once, per sample.
    const auto start = std::chrono::steady_clock::now();
    Eigen::Matrix3Xd x;
    for (int i = 0; i < f_count; ++i) {
      const std::vector<Eigen::Matrix3Xd> inputs{c.shape(a, i), c.shape(b, i)};
      NonlinearBlendInputs prepared;
      nonlinear_blend_prepare(data, inputs, &prepared);
      nonlinear_blend_solve(data, prepared, std::array<double, 2>{0.5, 0.5}, &x);
    }
    const std::chrono::duration<double> elapsed = std::chrono::steady_clock::now() - start;
    table.nonlinear.seconds_per_frame = elapsed.count() / f_count;
  }

  // Figure 4: five weights at the sample where linear blending errs most.
  {
    const int i = table.figure_sample;
    const double t = t_of(i, f_count);
    const std::vector<Eigen::Matrix3Xd> inputs{c.shape(a, i), c.shape(b, i)};
    NonlinearBlendInputs prepared;
    nonlinear_blend_prepare(data, inputs, &prepared);
    const double weights[5] = {0, 0.25, 0.5, 0.75, 1};
    std::vector<FigurePanel> panels(20);
    BlendedFrame out = make_blended_frame(linear_space);
    Eigen::Matrix3Xd x;
    double max_error = 0;
    std::vector<std::vector<float>> errors(15);
    for (int col = 0; col < 5; ++col) {
      const double s = weights[col];
      nonlinear_blend_solve(data, prepared, std::array<double, 2>{1 - s, s}, &x);
      panels[col].positions = x;
      panels[col].colors.assign(c.num_vertices, cv::Vec3b(200, 200, 200));
      const std::array<float, 2> w{static_cast<float>(1 - s), static_cast<float>(s)};
      const BlendSpace* spaces[3] = {&linear_space, &hybrid1, &hybrid3};
      for (int m = 0; m < 3; ++m) {
        m == 0 ? blend_linear(*spaces[m], t, w, &out) : blend_hybrid(*spaces[m], t, w, &out);
        panels[(m + 1) * 5 + col].positions = to_matrix(out);
        errors[m * 5 + col] = vertex_errors(out, x);
        max_error = std::max<double>(max_error, max_of(errors[m * 5 + col]));
      }
    }
    for (int m = 0; m < 3; ++m) {
      for (int col = 0; col < 5; ++col) {
        FigurePanel& p = panels[(m + 1) * 5 + col];
        for (float e : errors[m * 5 + col]) p.colors.push_back(heat_color(e, max_error));
      }
    }
    FigureLayout layout;
    layout.title = fmt::format("{}: {} (w = 0) to {} (w = 1), sample {} of {}; error vs non-linear",
                               c.name, table.take_a, table.take_b, i, f_count);
    layout.row_labels = {"non-linear", "linear", "hybrid, 1 ref", "hybrid, 3 refs"};
    for (double s : weights) layout.column_labels.push_back(fmt::format("w = {:.2f}", s));
    layout.bar_label = fmt::format("{:.1f} mm", 1000 * max_error);
    layout.bar_max = max_error;
    table.figure = render_figure(panels, c.triangles, layout);
  }
  return table;
}

nlohmann::json table1_json(const Table1& t) {
  auto row = [](const Table1Row& r) {
    return nlohmann::json{{"method", r.method},
                          {"references", r.references},
                          {"max_error_m", r.max_error_m},
                          {"max_error_pct", r.max_error_pct},
                          {"seconds_per_frame", r.seconds_per_frame}};
  };
  return {{"class", t.motion_class},
          {"take_a", t.take_a},
          {"take_b", t.take_b},
          {"mean_rotation_deg", t.rotation_deg},
          {"character_height_m", t.character_height},
          {"samples", t.samples},
          {"test_weights", t.test_weights},
          {"figure_sample", t.figure_sample},
          {"rows", {row(t.linear), row(t.hybrid1), row(t.hybrid3), row(t.nonlinear)}},
          {"linear_max_error_pct", t.linear.max_error_pct},
          {"hybrid1_max_error_pct", t.hybrid1.max_error_pct},
          {"hybrid3_max_error_pct", t.hybrid3.max_error_pct}};
}

}  // namespace fourd
