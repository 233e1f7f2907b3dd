// The segment stage over a session: the method, the per-camera models, every selected frame's
// silhouettes, their checks, and segment/report.json.
#include <tbb/parallel_for.h>

#include <algorithm>
#include <map>
#include <nlohmann/json.hpp>
#include <optional>

#include "pipeline/core/capture.h"
#include "pipeline/core/colmap_model.h"
#include "pipeline/core/error.h"
#include "pipeline/core/files.h"
#include "pipeline/core/image_io.h"
#include "pipeline/core/log.h"
#include "stages/segment/consistency.h"
#include "stages/segment/plate.h"
#include "stages/segment/segment.h"

namespace fourd::segment {
namespace {

// A camera whose silhouette is less than this fraction explained by the visual hull of all
// cameras sees foreground the others do not. On the synthetic studios a correct key scores
// 0.97 and above (the hull is carved coarsely and generously); a key that took part of the
// backdrop, or a camera whose calibration is off, scores far less.
constexpr double kMinExplained = 0.85;
// Warnings logged one by one; the rest are counted in the log and listed in report.json.
constexpr std::size_t kMaxLoggedWarnings = 40;
// The performer's shadows are looked for on the floor within this fraction of the cameras'
// distance from the point they look at: the volume they share and a shadow's length beyond it.
constexpr double kShadowReach = 0.8;

struct Item {
  std::size_t take;
  int frame;
};

struct Coverage {
  double sum = 0, min = 1, max = 0;
  int frames = 0, empty = 0;
};

struct Explained {
  double sum = 0, min = 1;
  int frames = 0;
};

struct Warning {
  std::string take, camera;
  int frame = 0;
  std::string kind;  // foreground_fraction | inconsistent
  double value = 0;
  std::string message;
};

// Frames spread over every take to learn a per-camera model from.
std::vector<std::pair<std::size_t, int>> model_samples(const CaptureIndex& capture, int count) {
  std::vector<std::pair<std::size_t, int>> samples;
  std::size_t total = 0;
  for (const auto& t : capture.takes) total += t.frame_count;
  for (int i = 0; i < count; ++i) {
    std::size_t global = (2 * i + 1) * total / (2 * count);
    for (std::size_t t = 0; t < capture.takes.size(); ++t) {
      if (global < static_cast<std::size_t>(capture.takes[t].frame_count)) {
        samples.emplace_back(t, static_cast<int>(global));
        break;
      }
      global -= capture.takes[t].frame_count;
    }
  }
  return samples;
}

// plates/<camera>/<index>.png, in index order.
std::vector<cv::Mat> read_plates(const Session& session, const Camera& camera) {
  const fs::path dir = session.dir("plates") / camera.name;
  std::error_code ec;
  if (!fs::is_directory(dir, ec)) {
    throw InputError(fmt::format("{}: missing: no plates of the empty studio for camera {}",
                                 dir.string(), camera.name));
  }
  std::vector<fs::path> files;
  for (const auto& e : fs::directory_iterator(dir)) {
    const std::string name = e.path().filename().string();
    if (e.is_regular_file() && e.path().extension() == ".png" && name.front() != '.') {
      files.push_back(e.path());
    }
  }
  std::sort(files.begin(), files.end());
  if (files.empty()) {
    throw InputError(fmt::format("{}: no plate (.png) for camera {}", dir.string(), camera.name));
  }
  std::vector<cv::Mat> plates;
  for (const fs::path& f : files) {
    cv::Mat p = read_image(f);
    if (p.cols != camera.intrinsics.width || p.rows != camera.intrinsics.height) {
      throw InputError(fmt::format("{}: camera {}: the plate is {}x{}, the camera's images are {}x{}",
                                   f.string(), camera.name, p.cols, p.rows,
                                   camera.intrinsics.width, camera.intrinsics.height));
    }
    plates.push_back(std::move(p));
  }
  return plates;
}

// What every frame's silhouettes add to the report, summed in frame order.
struct Summary {
  std::vector<std::vector<Coverage>> coverage;        // per take and camera
  std::vector<std::vector<Explained>> explained_sum;  // per take and camera
  std::vector<Warning> warnings;
};

// The segment stage's steps over one session and the state they share: the cameras, the
// method and its per-camera models, every selected frame's measures, the report.
class SegmentRun {
 public:
  SegmentRun(const Session& session, const StageArgs& args)
      : session_(session),
        args_(args),
        options_(session_options(session)),
        cameras_(read_colmap_model(session.calibration_dir())),
        capture_(scan_capture(session, cameras_)),
        out_dir_(session.dir("segment")) {
    if (capture_.takes.empty()) {
      throw InputError(fmt::format("{}: no takes to segment", session.capture_dir().string()));
    }
  }

  // The frames of this job, checked before any work (--finish: their silhouettes exist).
  void select_items();
  // The method, and its per-camera models (the --finish job learns them again for the report).
  void learn_models();
  // Every selected frame's silhouettes segmented (or, --finish, read) and measured.
  void segment_frames();
  // The measures summed, warned about, and written to report.json.
  void report();

 private:
  static SegmentOptions session_options(const Session& session) {
    SegmentOptions options;
    session.stage_options("segment", options);
    return options;
  }
  fs::path silhouette_path(const std::string& take, std::size_t camera, int frame) const {
    return out_dir_ / take / cameras_[camera].name / (frame_name(frame) + ".png");
  }
  fs::path mask_path(const std::string& take, std::size_t camera, int frame) const {
    return session_.dir("masks") / take / cameras_[camera].name / (frame_name(frame) + ".png");
  }
  void check_silhouettes_exist() const;
  void learn_chroma();
  void learn_plates();
  void require_space() const;
  void segment_item(std::size_t i, log::Progress& progress);
  cv::Mat silhouette(const std::string& take, std::size_t c, int frame, cv::Mat* image,
                     cv::Mat* doubtful, cv::Mat* off_plate) const;
  Summary summarise() const;
  void add_summary(const Summary& summary);

  const Session& session_;
  const StageArgs& args_;
  const SegmentOptions options_;
  const std::vector<Camera> cameras_;
  const CaptureIndex capture_;
  const fs::path out_dir_;
  std::vector<Item> items_;
  MethodChoice choice_;
  std::optional<ConsistencyCheck> consistency_;
  std::vector<Backdrop> backdrops_;
  std::vector<KeyModel> keys_;
  std::vector<PlateModel> plates_;
  bool shadow_floor_ = false;  // plate: shadows only on the floor around the rig's centre
  std::vector<double> fractions_, explained_;  // per item and camera
  nlohmann::json report_;
};

void SegmentRun::select_items() {
  check_frame_selection(args_.selection, capture_);
  for (std::size_t t = 0; t < capture_.takes.size(); ++t) {
    for (int f = 0; f < capture_.takes[t].frame_count; ++f) {
      if (args_.selection.selects(capture_.takes[t].name, f)) items_.push_back({t, f});
    }
  }
  if (items_.empty()) {
    throw InputError(fmt::format("--take '{}' --frames {} selects no frame of the capture",
                                 args_.selection.take, args_.selection.frames_text()));
  }
  if (args_.finish) check_silhouettes_exist();
}

void SegmentRun::check_silhouettes_exist() const {
  for (const Item& item : items_) {
    for (std::size_t c = 0; c < cameras_.size(); ++c) {
      const fs::path p = silhouette_path(capture_.takes[item.take].name, c, item.frame);
      std::error_code ec;
      if (!fs::is_regular_file(p, ec)) {
        throw InputError(fmt::format("segment --finish: {} is missing (take {} camera {} frame "
                                     "{}): its job has not run or failed",
                                     p.string(), capture_.takes[item.take].name,
                                     cameras_[c].name, item.frame));
      }
    }
  }
}

void SegmentRun::learn_models() {
  choice_ = choose_method(session_.root(), options_.method);
  log::info("method {} ({})", choice_.method, choice_.reason);
  report_["method"] = choice_.method;
  report_["reason"] = choice_.reason;

  consistency_.emplace(cameras_);
  if (!consistency_->usable()) {
    log::info("no cross-camera check: {} camera(s) share too little of the volume",
              cameras_.size());
  }
  backdrops_.resize(cameras_.size());
  keys_.resize(cameras_.size());
  plates_.resize(cameras_.size());
  if (choice_.method == "chroma") {
    learn_chroma();
  } else if (choice_.method == "plate") {
    learn_plates();
  }
}

// Method chroma: every camera's backdrop colour and key, from frames spread over the takes.
void SegmentRun::learn_chroma() {
  const auto samples = model_samples(capture_, options_.model_frames);
  tbb::parallel_for(std::size_t{0}, cameras_.size(), [&](std::size_t c) {
    std::vector<cv::Mat> frames, maps;
    for (const auto& [t, f] : samples) {
      frames.push_back(read_capture_image(session_, cameras_[c], capture_.takes[t].name, f));
    }
    backdrops_[c] = learn_backdrop(frames, cameras_[c].name);
    for (const cv::Mat& frame : frames) {
      maps.push_back(keyness(frame, backdrops_[c], options_.key_offset));
    }
    keys_[c] = learn_key(maps);
  });
  for (std::size_t c = 0; c < cameras_.size(); ++c) {
    const Backdrop& b = backdrops_[c];
    log::info("camera {}: backdrop RGB ({:.0f}, {:.0f}, {:.0f}), hue {:.1f} deg, {:.0f}% of the "
              "pixels; keyness < {:.3f} is the performer, > {:.3f} the backdrop (learned from "
              "{} frames)", cameras_[c].name, b.rgb[0], b.rgb[1], b.rgb[2], b.hue_deg,
              100 * b.fraction, keys_[c].foreground_below, keys_[c].backdrop_above,
              samples.size());
    report_["backdrop"][cameras_[c].name] = {{"rgb", {b.rgb[0], b.rgb[1], b.rgb[2]}},
                                             {"hue_deg", b.hue_deg},
                                             {"fraction", b.fraction}};
    report_["key"][cameras_[c].name] = {{"foreground_below", keys_[c].foreground_below},
                                        {"backdrop_above", keys_[c].backdrop_above}};
  }
}

// Method plate: every camera's background model from its plates of the empty studio.
void SegmentRun::learn_plates() {
  const ConsistencyCheck& consistency = *consistency_;
  // The performer's shadows fall on the floor (z = 0) around where the cameras look; without
  // a floor below that point (it lies at or under z = 0) they may be anywhere.
  shadow_floor_ = consistency.has_aim() && consistency.aim_centre().z() > 0;
  if (shadow_floor_) {
    log::info("shadows only on the floor within {:.3g} m of ({:.3g}, {:.3g})",
              kShadowReach * consistency.aim_reach(), consistency.aim_centre().x(),
              consistency.aim_centre().y());
  } else {
    log::info("shadows anywhere: the cameras do not look at a point above the floor z = 0");
  }
  tbb::parallel_for(std::size_t{0}, cameras_.size(), [&](std::size_t c) {
    plates_[c] = learn_plate(read_plates(session_, cameras_[c]), cameras_[c].name);
    if (shadow_floor_) {
      plates_[c].shadow_region = floor_shadow_region(cameras_[c], consistency.aim_centre(),
                                                     kShadowReach * consistency.aim_reach());
    }
  });
  for (std::size_t c = 0; c < cameras_.size(); ++c) {
    log::info("camera {}: background model from {} plate(s), noise {:.2f} grey levels",
              cameras_[c].name, plates_[c].plates, plates_[c].sigma);
    report_["plates"][cameras_[c].name] = {{"count", plates_[c].plates},
                                           {"noise_sigma", plates_[c].sigma}};
  }
}

// Room for the masks: one 8-bit mask per camera and frame, uncompressed at most.
void SegmentRun::require_space() const {
  std::uintmax_t pixels = 0;
  for (const Camera& cam : cameras_) {
    pixels += static_cast<std::uintmax_t>(cam.intrinsics.width) * cam.intrinsics.height;
  }
  require_free_space(out_dir_, items_.size() * pixels,
                     fmt::format("segment's masks of {} frames of {} cameras", items_.size(),
                                 cameras_.size()));
}

void SegmentRun::segment_frames() {
  if (!args_.finish) require_space();
  const std::size_t nc = cameras_.size();
  fractions_.assign(items_.size() * nc, 0.0);
  explained_.assign(items_.size() * nc, -1.0);
  log::Progress progress(args_.finish ? "checking silhouettes" : "segmenting frames",
                         items_.size());
  tbb::parallel_for(std::size_t{0}, items_.size(),
                    [&](std::size_t i) { segment_item(i, progress); });
}

// Camera c's silhouette of a frame: read (--finish), the supplied mask, or segmented (the
// image it was segmented from in `image`; plate: the pixels for the cross-camera recoveries in
// `doubtful` and `off_plate`).
cv::Mat SegmentRun::silhouette(const std::string& take, std::size_t c, int frame, cv::Mat* image,
                               cv::Mat* doubtful, cv::Mat* off_plate) const {
  if (args_.finish) return read_image(silhouette_path(take, c, frame), cv::IMREAD_GRAYSCALE);
  if (choice_.method == "masks") {
    return read_supplied_mask(mask_path(take, c, frame), cameras_[c].name,
                              cameras_[c].intrinsics.width, cameras_[c].intrinsics.height, frame);
  }
  *image = read_capture_image(session_, cameras_[c], take, frame);
  return choice_.method == "plate"
             ? plate_silhouette(*image, plates_[c], options_, doubtful, off_plate)
             : key_silhouette(*image, backdrops_[c], keys_[c], options_);
}

// One frame: every camera's silhouette, written, and its foreground fraction and consistency.
void SegmentRun::segment_item(std::size_t i, log::Progress& progress) {
  const std::size_t nc = cameras_.size();
  const Item& item = items_[i];
  const std::string& take = capture_.takes[item.take].name;
  std::vector<cv::Mat> masks(nc), doubtful(nc), off_plate(nc), images(nc);
  for (std::size_t c = 0; c < nc; ++c) {
    masks[c] = silhouette(take, c, item.frame, &images[c], &doubtful[c], &off_plate[c]);
  }
  // Plate with shadows anywhere: what one camera took for shadow, others may see as the
  // performer. Not with shadows only on the floor: there the coarse hull cannot tell the
  // shadow between the feet from the feet (room studio: segment.iou_mean 0.932 with, 0.950
  // without).
  if (!args_.finish && choice_.method == "plate" && !shadow_floor_) {
    consistency_->recover(masks, doubtful);
    for (cv::Mat& mask : masks) clean_up(mask, options_);
  }
  // Plate: the performer where one camera cannot tell it from the plate (camouflage, a shoe as
  // dark as a shadow), from the others' silhouettes, pixel by pixel. Plate studio recipe:
  // segment.iou_mean 0.961 -> 0.966 (worst 0.926 -> 0.943). Then the final outline, by its
  // coverage smoothed over the neighbours: 0.9684 -> 0.9714 (worst 0.9467 -> 0.9493).
  if (!args_.finish && choice_.method == "plate") {
    consistency_->recover_hidden(masks, off_plate, shadow_floor_);
    for (std::size_t c = 0; c < nc; ++c) refine_plate_outline(masks[c], images[c], plates_[c]);
  }
  for (std::size_t c = 0; c < nc; ++c) {
    const cv::Mat& mask = masks[c];
    if (!args_.finish) {
      write_image_atomic(silhouette_path(take, c, item.frame), mask,
                         {cv::IMWRITE_PNG_COMPRESSION, 1});
    }
    fractions_[i * nc + c] = cv::countNonZero(mask) / static_cast<double>(mask.total());
  }
  const std::vector<double> e = consistency_->explained(masks);
  std::copy(e.begin(), e.end(), explained_.begin() + static_cast<std::ptrdiff_t>(i * nc));
  progress.step();
}

// Summed and warned in frame order, so the report does not depend on the threads or the
// job split.
Summary SegmentRun::summarise() const {
  const std::size_t nc = cameras_.size();
  Summary s{std::vector<std::vector<Coverage>>(capture_.takes.size(), std::vector<Coverage>(nc)),
            std::vector<std::vector<Explained>>(capture_.takes.size(), std::vector<Explained>(nc)),
            {}};
  for (std::size_t i = 0; i < items_.size(); ++i) {
    const std::string& take = capture_.takes[items_[i].take].name;
    for (std::size_t c = 0; c < nc; ++c) {
      const double fraction = fractions_[i * nc + c];
      Coverage& cov = s.coverage[items_[i].take][c];
      cov.sum += fraction;
      cov.min = std::min(cov.min, fraction);
      cov.max = std::max(cov.max, fraction);
      cov.frames += 1;
      cov.empty += fraction == 0;
      if (fraction < options_.warn_foreground_min || fraction > options_.warn_foreground_max) {
        s.warnings.push_back(
            {take, cameras_[c].name, items_[i].frame, "foreground_fraction", fraction,
             fmt::format("take {} camera {} frame {}: foreground covers {:.2f}% of the image, "
                         "outside [{:.2f}%, {:.2f}%]: check the segmentation or whether the "
                         "camera sees the volume",
                         take, cameras_[c].name, items_[i].frame, 100 * fraction,
                         100 * options_.warn_foreground_min, 100 * options_.warn_foreground_max)});
      }
      const double e = explained_[i * nc + c];
      if (e < 0) continue;
      Explained& ex = s.explained_sum[items_[i].take][c];
      ex.sum += e;
      ex.min = std::min(ex.min, e);
      ex.frames += 1;
      if (e < kMinExplained) {
        s.warnings.push_back(
            {take, cameras_[c].name, items_[i].frame, "inconsistent", e,
             fmt::format("take {} camera {} frame {}: only {:.0f}% of the silhouette is seen by "
                         "the other cameras (their visual hull): the segmentation took "
                         "background, or the calibration is off",
                         take, cameras_[c].name, items_[i].frame, 100 * e)});
      }
    }
  }
  return s;
}

// Per take and camera foreground fraction and consistency, so a bad key is visible at a
// glance, and the warnings.
void SegmentRun::add_summary(const Summary& summary) {
  const std::size_t nc = cameras_.size();
  for (std::size_t t = 0; t < capture_.takes.size(); ++t) {
    for (std::size_t c = 0; c < nc; ++c) {
      const Coverage& cov = summary.coverage[t][c];
      if (cov.frames == 0) continue;
      report_["foreground_fraction"][capture_.takes[t].name][cameras_[c].name] = {
          {"mean", cov.sum / cov.frames}, {"min", cov.min}, {"max", cov.max},
          {"frames", cov.frames}, {"empty_frames", cov.empty}};
      const Explained& ex = summary.explained_sum[t][c];
      if (ex.frames == 0) continue;
      report_["explained"][capture_.takes[t].name][cameras_[c].name] = {
          {"mean", ex.sum / ex.frames}, {"min", ex.min}, {"frames", ex.frames}};
    }
  }
  nlohmann::json list = nlohmann::json::array();
  for (const Warning& w : summary.warnings) {
    list.push_back({{"take", w.take}, {"camera", w.camera}, {"frame", w.frame},
                    {"kind", w.kind}, {"value", w.value}, {"message", w.message}});
  }
  report_["warning_count"] = summary.warnings.size();
  report_["warnings"] = list;
}

void SegmentRun::report() {
  const Summary summary = summarise();
  const std::vector<Warning>& warnings = summary.warnings;
  for (std::size_t w = 0; w < warnings.size() && w < kMaxLoggedWarnings; ++w) {
    log::warn("{}", warnings[w].message);
  }
  if (warnings.size() > kMaxLoggedWarnings) {
    log::warn("... and {} more warnings about silhouettes (segment/report.json lists them)",
              warnings.size() - kMaxLoggedWarnings);
  }
  if (!warnings.empty()) {
    log::warn("{} warning(s) about {} silhouettes: the segmentation may have failed",
              warnings.size(), items_.size() * cameras_.size());
  }
  add_summary(summary);
  // A job of a split run leaves the reports to the --finish job (which sees every frame).
  if (args_.selection.whole()) {
    write_file_atomic(out_dir_ / "report.json", report_.dump(1) + "\n");
    YAML::Emitter used;
    used << to_yaml(options_);
    write_file_atomic(out_dir_ / "options.yaml", std::string(used.c_str()) + "\n");
  }
}

}  // namespace

void run_segment(const Session& session, const StageArgs& args) {
  SegmentRun run(session, args);
  run.select_items();
  run.learn_models();
  run.segment_frames();
  run.report();
}

}  // namespace fourd::segment
