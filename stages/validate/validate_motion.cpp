// Validation of the motion stages: timewarp (phase against the ground-truth phase), the motion
// spaces (the paper's Table 1 and parameter accuracy, under the stage name "blend") and the
// motion graph (the paper's Table 2, under "transitions"). Each reads what its stage wrote for
// the pipeline run (<stage>/) and the oracle run (<stage>_oracle/), whichever exist.
#include <fmt/format.h>

#include <cmath>
#include <numbers>

#include "pipeline/core/error.h"
#include "pipeline/core/files.h"
#include "stages/validate/validate.h"

namespace fourd::validate {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;

double wrap_half(double x) { return x - std::floor(x + 0.5); }  // into [-0.5, 0.5)

struct PhaseErrors {
  double sum = 0, max = 0;
  int count = 0;
  void add(double e) {
    sum += e;
    max = std::max(max, e);
    ++count;
  }
  double mean() const { return count ? sum / count : 0; }
};

// One class: the estimated t of every frame against the ground-truth phase. A cyclic class's
// phase origin is arbitrary (removed as the circular mean difference over the class); a
// one-shot class's t runs from its first frame (0) to its last (1), as does the truth rescaled.
// Errors in frames of the take (cycle frames for a cyclic take).
void class_phase_errors(const Session& session, const json& warp, PhaseErrors* errors,
                        std::string* table) {
  const bool cyclic = warp.at("cyclic").get<bool>();
  struct Frame {
    double diff;
    double frames_per_unit;
  };
  std::vector<Frame> frames;
  for (const json& take : warp.at("takes")) {
    const std::string name = take.at("take").get<std::string>();
    const fs::path truth_file = session.ground_truth_dir() / "takes" / (name + ".json");
    const json truth = read_json(truth_file);
    const std::vector<double> phase = truth.at("phase").get<std::vector<double>>();
    const std::vector<double> t = take.at("frame_t").get<std::vector<double>>();
    if (phase.size() != t.size()) {
      throw InputError(fmt::format("take {}: {} frames in the time warp but {} in {}", name,
                                   t.size(), phase.size(), truth_file.string()));
    }
    const double n = static_cast<double>(t.size());
    const double unit = cyclic ? truth.at("cycle_frames").get<double>() : std::max(1.0, n - 1);
    for (std::size_t f = 0; f < t.size(); ++f) {
      const double truth_t = cyclic ? phase[f] : phase[f] * n / std::max(1.0, n - 1);
      frames.push_back({cyclic ? wrap_half(t[f] - truth_t) : t[f] - truth_t, unit});
    }
  }
  double offset = 0;
  if (cyclic && !frames.empty()) {
    double s = 0, c = 0;
    for (const Frame& f : frames) {
      s += std::sin(2 * std::numbers::pi * f.diff);
      c += std::cos(2 * std::numbers::pi * f.diff);
    }
    offset = std::atan2(s, c) / (2 * std::numbers::pi);
  }
  PhaseErrors local;
  for (const Frame& f : frames) {
    const double e = std::abs(cyclic ? wrap_half(f.diff - offset) : f.diff) * f.frames_per_unit;
    local.add(e);
    errors->add(e);
  }
  *table += fmt::format("| {} | {} | {} | {:.3f} | {:.3f} |\n",
                        warp.at("class").get<std::string>(), cyclic ? "cyclic" : "one-shot",
                        frames.size(), local.mean(), local.max);
}

// A cyclic class: every take's period as timewarp found it (the cycle it loops on) against the
// true gait cycle, and that cycle's closure error. Adds a table row per take to `table`. A take
// whose summary has no cycle (written before timewarp recorded one) is left out.
struct PeriodErrors {
  double worst = 0, worst_closure_mm = 0;
  int takes = 0;
};
void class_period_errors(const Session& session, const json& warp, PeriodErrors* errors, std::string* table) {
  if (!warp.at("cyclic").get<bool>()) return;
  for (const json& take : warp.at("takes")) {
    if (!take.contains("cycle_frames")) continue;
    const std::string name = take.at("take").get<std::string>();
    const json truth = read_json(session.ground_truth_dir() / "takes" / (name + ".json"));
    const double true_period = truth.at("cycle_frames").get<double>();
    const double found = take.at("cycle_frames").get<double>();
    const double closure_mm = 1000 * take.at("closure_rms_m").get<double>();
    const double error = std::abs(found - true_period);
    errors->worst = std::max(errors->worst, error);
    errors->worst_closure_mm = std::max(errors->worst_closure_mm, closure_mm);
    ++errors->takes;
    *table += fmt::format("| {} | {} | {:.3f} | {:.3f} | {:.3f} | {:.1f} | {:.3f} |\n", warp.at("class").get<std::string>(),
                          name, true_period, found, error, closure_mm, take.at("closure_ratio").get<double>());
  }
}

}  // namespace

StageReport validate_timewarp(const ValidationContext& ctx) {
  StageReport report;
  const std::vector<RunFolder> runs = run_folders(ctx.session, "timewarp", "options.yaml");
  if (runs.empty() || !fs::exists(ctx.session.ground_truth_dir() / "takes")) {
    report.summary = "Skipped: no timewarp/ output, or no ground truth to compare with.";
    return report;
  }
  report.present = true;
  report.summary = "Phase of every frame of every take after time-warp registration, against the "
                   "ground-truth phase (frames of the take's cycle, or of the one-shot take); the "
                   "period of every cyclic take's cycle against the true gait cycle, and its "
                   "closure error.";
  for (const RunFolder& run : runs) {
    PhaseErrors errors;
    PeriodErrors periods;
    std::string table =
        fmt::format("**{}** inputs:\n\n| class | kind | frames | mean error [frames] | max "
                    "[frames] |\n|---|---|---:|---:|---:|\n",
                    run.label);
    std::string period_table =
        "| class | take | true period [frames] | found | error | closure [mm] | closure ratio |\n"
        "|---|---|---:|---:|---:|---:|---:|\n";
    for (const MotionClassConfig& motion : ctx.session.config().motions) {
      const fs::path file = run.dir / (motion.name + ".json");
      if (!fs::exists(file)) continue;
      const json warp = read_json(file);
      class_phase_errors(ctx.session, warp, &errors, &table);
      class_period_errors(ctx.session, warp, &periods, &period_table);
    }
    report.details += table + "\n";
    report.metrics.push_back({"phase_error_frames", errors.mean(), run.input,
                              "mean phase error over every frame [frames]"});
    report.metrics.push_back({"phase_error_max_frames", errors.max, run.input,
                              "largest phase error [frames]"});
    if (periods.takes > 0) {
      report.details += fmt::format("Cycle periods, {} inputs (the cycle each take loops on):\n\n", run.label) +
                        period_table + "\n";
      report.metrics.push_back({"period_error_frames", periods.worst, run.input,
                                "largest |found - true| gait cycle over the cyclic takes [frames]"});
      report.metrics.push_back({"closure_rms_max_mm", periods.worst_closure_mm, run.input,
                                "largest closure error of a take's cycle [mm]"});
    }
  }
  return report;
}

StageReport validate_blend(const ValidationContext& ctx) {
  StageReport report;
  const std::vector<RunFolder> runs = run_folders(ctx.session, "motionspace", "summary.json");
  if (runs.empty()) {
    report.summary = "Skipped: no motionspace/ output.";
    return report;
  }
  report.present = true;
  report.summary = "The paper's Table 1 on the pair of takes whose shapes differ most in rotation "
                   "(max vertex error against the non-linear blend, % of the character's "
                   "height), and the high-level parameter measured on blended motions against "
                   "the requested one (% of the parameter's range).";
  for (const RunFolder& run : runs) {
    const json summary = read_json(run.dir / "summary.json");
    report.metrics.push_back({"parameter_error_pct", summary.at("parameter_error_pct").get<double>(),
                              run.input, "largest parameter error, % of the range"});
    if (!summary.contains("table1")) continue;
    const json& t1 = summary.at("table1");
    std::string table = fmt::format(
        "**{}** inputs, class {} ({} / {}, {:.1f} deg mean rotation):\n\n| method | max error "
        "[% height] | time per frame [s] |\n|---|---:|---:|\n",
        run.label, t1.value("class", ""), t1.value("take_a", ""), t1.value("take_b", ""),
        t1.value("mean_rotation_deg", 0.0));
    double linear_s = 0, hybrid3_s = 0;
    for (const json& row : t1.at("rows")) {
      const std::string method = row.at("method").get<std::string>();
      const double s = row.at("seconds_per_frame").get<double>();
      table += fmt::format("| {} | {:.3f} | {:.3g} |\n", method,
                           row.at("max_error_pct").get<double>(), s);
      if (method == "linear") linear_s = s;
      if (row.at("references").get<int>() == 3) hybrid3_s = s;
    }
    report.details += table + "\n";
    for (const char* name :
         {"linear_max_error_pct", "hybrid1_max_error_pct", "hybrid3_max_error_pct"}) {
      report.metrics.push_back({name, t1.at(name).get<double>(), run.input,
                                "max vertex error against the non-linear blend, % of height"});
    }
    if (linear_s > 0) {
      report.metrics.push_back({"hybrid3_cost_ratio_to_linear", hybrid3_s / linear_s, run.input,
                                "time per frame of hybrid (3 references) / linear"});
    }
    const fs::path figure = run.dir / "figure4.png";
    if (fs::exists(figure)) {
      Picture p;
      p.file = fmt::format("blend_figure4_{}.png", run.label);
      write_file_atomic(ctx.reports_dir / p.file, read_file(figure));
      p.caption = fmt::format("blend ({} inputs): five weights side by side, error heat-maps of "
                              "linear and hybrid blending against non-linear (paper Figure 4)",
                              run.label);
      report.pictures.push_back(p);
    }
  }
  return report;
}

StageReport validate_transitions(const ValidationContext& ctx) {
  StageReport report;
  const std::vector<RunFolder> runs = run_folders(ctx.session, "graph", "table2.json");
  if (runs.empty()) {
    report.summary = "Skipped: no graph/table2.json.";
    return report;
  }
  report.present = true;
  report.summary = "The paper's Table 2: random transition requests answered by the online "
                   "trellis search and by the precomputed baseline. E_S measured on the frames "
                   "played at the switch (cost units of the asset), latency in seconds.";
  for (const RunFolder& run : runs) {
    const json t2 = read_json(run.dir / "table2.json");
    std::string table = fmt::format(
        "**{}** inputs, {} requests:\n\n| method | E_S | lambda E_L | latency [s] | online CPU "
        "[s] | offline CPU [s] | answered |\n|---|---:|---:|---:|---:|---:|---:|\n",
        run.label, t2.at("requests").get<int>());
    for (const json& row : t2.at("rows")) {
      const int depth = row.at("depth").get<int>(), n = row.at("precomputed").get<int>();
      const bool limited = row.value("rate_limited", true);
      const std::string id = n > 0 ? fmt::format("precomputed{}{}", n, limited ? "" : "_instant")
                                   : fmt::format("online_depth{}", depth);
      const double es = row.at("played_similarity_cost").get<double>();
      const double el = row.at("latency_cost").get<double>();
      const double latency = row.at("latency_s").get<double>();
      const double online = row.at("online_cpu_s").get<double>();
      const double offline = row.at("offline_cpu_s").get<double>();
      table += fmt::format("| {} | {:.2f} | {:.2f} | {:.3f} | {:.2g} | {:.3g} | {} |\n",
                           row.at("method").get<std::string>(), es, el, latency, online, offline,
                           row.at("answered").get<int>());
      const std::string what = row.at("method").get<std::string>();
      report.metrics.push_back({id + "_es", es, run.input, what + ": mean E_S(P_opt)"});
      report.metrics.push_back({id + "_lambda_el", el, run.input, what + ": mean lambda E_L"});
      report.metrics.push_back({id + "_latency_s", latency, run.input, what + ": mean latency [s]"});
      report.metrics.push_back({id + "_online_cpu_s", online, run.input,
                                what + ": CPU per transition [s]"});
      report.metrics.push_back({id + "_offline_cpu_s", offline, run.input,
                                what + ": offline precomputation [s]"});
    }
    report.details += table + "\n";
  }
  return report;
}

StageReport validate_graph(const ValidationContext& ctx) {
  StageReport report;
  const std::vector<RunFolder> runs = run_folders(ctx.session, "graph", "table2.json");
  report.summary = "Transitions as the runtime plays them: the Table 2 requests played by a "
                   "character at the capture frame rate; per transition, the worst per-frame "
                   "vertex displacement over the larger of the two motions' own 99th-percentile "
                   "per-frame displacement (1: no vertex moves faster than in the captured "
                   "motions).";
  for (const RunFolder& run : runs) {
    const json t2 = read_json(run.dir / "table2.json");
    if (!t2.contains("transition_jump")) continue;
    const json& j = t2.at("transition_jump");
    if (j.at("played").get<int>() == 0) continue;
    report.present = true;
    const double worst = j.at("worst_ratio").get<double>();
    const double median = j.at("median_ratio").get<double>();
    const double worst_mm = j.at("worst_displacement_mm").get<double>();
    report.metrics.push_back({"transition_jump_ratio_worst", worst, run.input,
                              "worst per-frame vertex jump during a transition / the motions' p99"});
    report.metrics.push_back({"transition_jump_ratio_median", median, run.input,
                              "median over the transitions of the same ratio"});
    report.metrics.push_back({"transition_jump_worst_mm", worst_mm, run.input,
                              "worst per-frame vertex displacement during a transition [mm]"});
    report.details += fmt::format(
        "**{}**: {} of {} requests played (online search, depth {}): jump ratio worst {:.2f}, "
        "median {:.2f}; worst displacement {:.1f} mm per frame.\n\n",
        run.label, j.at("played").get<int>(), t2.at("requests").get<int>(),
        j.at("depth").get<int>(), worst, median, worst_mm);
  }
  if (!report.present) report.summary = "Skipped: no graph/table2.json with played transitions.";
  return report;
}

}  // namespace fourd::validate
