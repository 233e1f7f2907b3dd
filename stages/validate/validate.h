#pragma once
// The validation stage: compares each stage's outputs with the ground truth of a synthetic
// session and writes reports/metrics.json (machine-readable, stable) and reports/report.md
// (Markdown with pictures).
//
// metrics.json scheme (docs/design.md "Validation contract"): one object per stage; a metric that
// depends on which inputs the stage ran on sits under "pipeline" or "oracle", the others
// directly under the stage:
//
//   {"synth": {"takes": 4, "frames": 120, ...},
//    "align": {"pipeline": {"correspondence_rms_mm": 8.1}, "oracle": {...}}}
//
// Flattened with '.', the keys read "<stage>.<metric>" or "<stage>.<input>.<metric>", with the
// unit in the metric name; tools/check_metrics.py matches them that way.
//
// Adding a stage: write `StageReport validate_<stage>(const ValidationContext&)` (in its own
// .cpp here) and list it in validators(). A validator returns present = false, without
// failing, when the stage's outputs are absent.
#include <filesystem>
#include <functional>
#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>
#include <string>
#include <utility>
#include <vector>

#include "pipeline/core/config.h"
#include "pipeline/core/mesh.h"
#include "pipeline/core/session.h"

namespace fourd::validate {

// The options are the members visit() lists, with their help; the others are tuned values,
// not options (docs/validate.md, "Advanced").
struct ValidateOptions {
  int frames_per_take = 5;
  int picture_takes = 4;
  int picture_cameras = 2;  // cameras per picture, spread evenly around the rig
  int panel_width = 480;    // largest width of one image panel in the pictures [px]
  template <class V>
  void visit(V& v) {
    v("frames_per_take", frames_per_take,
      "frames sampled evenly per take for the per-frame checks", Range{1, 100000});
    v("picture_takes", picture_takes, "takes pictured in the report (the first ones, by name)",
      Range{0, 1000});
  }
};

// Which inputs a metric was computed on (docs/design.md "Oracle inputs"). kNone: the metric does
// not depend on it (synth's own checks, counts).
enum class InputKind { kNone, kPipeline, kOracle };

struct Metric {
  std::string name;  // with its unit: "correspondence_rms_mm", "capture_mb"
  double value = 0;
  InputKind input = InputKind::kNone;
  std::string meaning;  // one line for report.md
};

struct Picture {
  std::string file;  // relative to reports/
  std::string caption;
};

struct StageReport {
  std::string stage;
  bool present = false;  // the stage's outputs exist and were validated
  std::string summary;   // what was checked, or why the stage was skipped (Markdown)
  std::string details;   // further Markdown (tables) for report.md; may be empty
  std::vector<Metric> metrics;
  std::vector<Picture> pictures;
  std::string error;  // set by run_validation when the validator threw
};

struct ValidationContext {
  const Session& session;
  const ValidateOptions& options;
  std::filesystem::path reports_dir;  // where pictures go
};

// A stage's output folder of one run: <stage>/ (pipeline inputs) or <stage>_oracle/.
struct RunFolder {
  std::filesystem::path dir;
  InputKind input;
  const char* label;  // "pipeline" | "oracle"
};
// <stage>/ and <stage>_oracle/, those that hold `marker` (a file the stage writes last).
std::vector<RunFolder> run_folders(const Session& session, const std::string& stage,
                                   const std::string& marker);
// Parses a JSON file; InputError naming it when it is not valid JSON.
nlohmann::json read_json(const std::filesystem::path& path);

using Validator = std::function<StageReport(const ValidationContext&)>;
struct ValidatorEntry {
  std::string stage;
  Validator run;
};

// One validator per stage, in pipeline order.
const std::vector<ValidatorEntry>& validators();

// The synth validator: counts, capture size, and whether the ground-truth meshes project
// inside the ground-truth silhouettes (pictures: capture next to the silhouette contour).
StageReport validate_synth(const ValidationContext& context);
// Timewarp: phase of every frame against the ground-truth phase (timewarp.phase_error_frames).
StageReport validate_timewarp(const ValidationContext& context);
// Motion spaces: Table 1 and parameter accuracy from motionspace/summary.json (blend.*).
StageReport validate_blend(const ValidationContext& context);
// Motion graph: Table 2 from graph/table2.json (transitions.*).
StageReport validate_transitions(const ValidationContext& context);
// Transitions as played: the jump ratio of the Table 2 requests played by a character
// (graph.transition_jump_ratio_worst / _median, graph.transition_jump_worst_mm).
StageReport validate_graph(const ValidationContext& context);
// Textures: texture/ and texture_oracle/ rendered into the studio cameras against the captured
// images inside the ground-truth silhouettes (texture.psnr_db), unseen texels, seams, time
// (validate_texture.cpp).
StageReport validate_texture(const ValidationContext& context);

// How much a take's baked textures flicker: the mean absolute change of a chart texel's colour
// between consecutive frames [8-bit levels], over the texels inside the atlas's charts (`atlas`
// UVs), pooled over every consecutive pair of frames 0..n-1 of each take in `frames_per_take`.
// Texture files are <dir>/<take>/<frame><extension>.
double texture_flicker(const std::filesystem::path& dir, const std::string& extension,
                       const std::vector<std::pair<std::string, int>>& frames_per_take,
                       const Mesh& atlas);

// Path following of the runtime: every control script with a path in the session's play/
// folder played on asset/ and asset_oracle/ (distance from the path, length error; top-down
// plots), and a transition filmstrip at several trellis depths (paper Figure 7)
// (validate_paths.cpp).
StageReport validate_paths(const ValidationContext& context);

// segment/ silhouettes against ground_truth/silhouettes/: segment.iou_mean (validate_segment.cpp).
StageReport validate_segment(const ValidationContext& context);
// Intersection over union of the foreground (> 127) of two silhouettes of one size, 1 when both
// are empty: the per camera and frame value segment.iou_mean averages. InputError when the sizes
// differ.
double silhouette_iou(const cv::Mat& a, const cv::Mat& b);

// reconstruct/ meshes (and visual_hull/) against ground_truth/meshes/: accuracy, completeness,
// F-score, seconds per frame, per take, plus error heat-maps (validate_reconstruct.cpp).
StageReport validate_reconstruct(const ValidationContext& context);

// align/ and align_oracle/ against ground_truth/meshes/: correspondence, surface, flipped
// triangles, seconds per frame, plot vs the sequential baseline (validate_align.cpp).
StageReport validate_align(const ValidationContext& context);

// Runs every validator and writes reports/metrics.json, reports/report.md and the pictures,
// each atomically. A validator that throws does not stop the others: its stage is reported as
// failed, both files are still written, and the first error is rethrown at the end.
std::vector<StageReport> run_validation(const Session& session, const ValidateOptions& options);

// The metrics.json document for `reports` (see the scheme above).
nlohmann::json metrics_json(const std::vector<StageReport>& reports);

// "synth.takes", "align.oracle.correspondence_rms_mm": the flattened key of a metric.
std::string metric_key(const std::string& stage, const Metric& metric);

}  // namespace fourd::validate
