// Validation of the segment stage: its silhouettes against the ground-truth ones.
//
//   segment/<take>/<camera>/<frame>.png                  what segment wrote (0/255)
//   ground_truth/silhouettes/<take>/<camera>/<frame>.png what synth rendered (0/255)
//
// Metric: intersection over union of foreground pixels per camera and frame (sampled frames),
// averaged; per take, and the worst camera/frame so a bad key is named.
#include <fmt/format.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <map>
#include <opencv2/core.hpp>

#include "pipeline/core/error.h"
#include "pipeline/core/image_io.h"
#include "stages/validate/sampling.h"
#include "stages/validate/validate.h"

namespace fourd::validate {
namespace {

namespace fs = std::filesystem;




struct Item {
  std::string take, camera;
  int frame = 0;
  double iou = 0;
  bool missing = false;  // segment/ has no silhouette for a ground-truth one
};

}  // namespace

double silhouette_iou(const cv::Mat& a, const cv::Mat& b) {
  if (a.size() != b.size()) {
    throw InputError(fmt::format("silhouettes of different sizes: {}x{} and {}x{}", a.cols,
                                 a.rows, b.cols, b.rows));
  }
  const cv::Mat fa = a > 127, fb = b > 127;
  const int inter = cv::countNonZero(fa & fb);
  const int uni = cv::countNonZero(fa | fb);
  return uni == 0 ? 1.0 : double(inter) / uni;
}

StageReport validate_segment(const ValidationContext& ctx) {
  const Session& session = ctx.session;
  StageReport report;
  report.stage = "segment";
  const fs::path seg_dir = session.root() / "segment";
  const fs::path truth_dir = session.ground_truth_dir() / "silhouettes";
  const std::vector<std::string> takes = subfolders(seg_dir);
  std::error_code ec;
  if (takes.empty() || !fs::is_directory(truth_dir, ec)) {
    report.summary = takes.empty() ? "Skipped: no segment/ output."
                                   : "Skipped: no ground_truth/silhouettes/ (not a synthetic "
                                     "session).";
    return report;
  }

  std::vector<Item> items;
  for (const std::string& take : takes) {
    for (const std::string& camera : subfolders(truth_dir / take)) {
      const int frames = frame_count(truth_dir / take / camera, ".png");
      for (int f : sample_frames(frames, ctx.options.frames_per_take)) {
        items.push_back({take, camera, f});
      }
    }
  }
  if (items.empty()) {
    report.summary = "Skipped: no ground-truth silhouette matches a take of segment/.";
    return report;
  }
  report.present = true;
  tbb::parallel_for(std::size_t{0}, items.size(), [&](std::size_t i) {
    Item& it = items[i];
    const fs::path mine = seg_dir / it.take / it.camera / (frame_name(it.frame) + ".png");
    if (!fs::exists(mine)) {
      it.missing = true;
      return;
    }
    const fs::path truth = truth_dir / it.take / it.camera / (frame_name(it.frame) + ".png");
    it.iou = silhouette_iou(read_image(mine, cv::IMREAD_GRAYSCALE),
                            read_image(truth, cv::IMREAD_GRAYSCALE));
  });

  std::map<std::string, std::pair<double, int>> per_take;
  double sum = 0;
  int n = 0, missing = 0;
  const Item* worst = nullptr;
  for (const Item& it : items) {
    if (it.missing) {
      ++missing;
      continue;
    }
    sum += it.iou;
    ++n;
    per_take[it.take].first += it.iou;
    per_take[it.take].second += 1;
    if (!worst || it.iou < worst->iou) worst = &it;
  }
  auto add = [&](const std::string& name, double value, const std::string& meaning) {
    report.metrics.push_back({name, value, InputKind::kNone, meaning});
  };
  if (n > 0) {
    add("iou_mean", sum / n,
        "mean intersection over union of segment/ silhouettes with the ground-truth ones "
        "(sampled frames, every camera); 1 is perfect");
    add("iou_min", worst->iou, fmt::format("worst camera/frame ({} {} frame {})", worst->take,
                                           worst->camera, worst->frame));
  }
  add("silhouettes_missing", missing,
      "sampled ground-truth silhouettes without a segment/ silhouette; should be 0");
  std::string table = "| take | IoU mean | silhouettes |\n|---|---:|---:|\n";
  for (const auto& [take, s] : per_take) {
    add(take + ".iou_mean", s.first / s.second, "mean IoU of take " + take);
    table += fmt::format("| {} | {:.4f} | {} |\n", take, s.first / s.second, s.second);
  }
  report.details = table;
  report.summary = fmt::format(
      "Compared {} silhouette(s) of {} take(s) ({} frame(s) per take and camera at most) with "
      "ground_truth/silhouettes/.{}",
      n, per_take.size(), ctx.options.frames_per_take,
      missing ? fmt::format(" {} silhouette(s) missing from segment/.", missing) : "");
  return report;
}

}  // namespace fourd::validate
