// The segment stage over a session: the method, the per-camera models, every selected frame's
// silhouettes, their checks, and segment/report.json.
#include <tbb/parallel_for.h>

#include <algorithm>
#include <map>
#include <nlohmann/json.hpp>

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

}  // namespace

void run_segment(const Session& session, const StageArgs& args) {
  SegmentOptions options;
  session.stage_options("segment", options);
  std::vector<Camera> cameras = read_colmap_model(session.calibration_dir());
  CaptureIndex capture = scan_capture(session, cameras);
  if (capture.takes.empty()) {
    throw InputError(fmt::format("{}: no takes to segment", session.capture_dir().string()));
  }
  const fs::path out_dir = session.dir("segment");
  auto silhouette_path = [&](const std::string& take, std::size_t camera, int frame) {
    return out_dir / take / cameras[camera].name / (frame_name(frame) + ".png");
  };
  auto mask_path = [&](const std::string& take, std::size_t camera, int frame) {
    return session.dir("masks") / take / cameras[camera].name / (frame_name(frame) + ".png");
  };

  // The frames of this job, checked before any work.
  check_frame_selection(args.selection, capture);
  std::vector<Item> items;
  for (std::size_t t = 0; t < capture.takes.size(); ++t) {
    for (int f = 0; f < capture.takes[t].frame_count; ++f) {
      if (args.selection.selects(capture.takes[t].name, f)) items.push_back({t, f});
    }
  }
  if (items.empty()) {
    throw InputError(fmt::format("--take '{}' --frames {} selects no frame of the capture",
                                 args.selection.take, args.selection.frames_text()));
  }
  if (args.finish) {
    for (const Item& item : items) {
      for (std::size_t c = 0; c < cameras.size(); ++c) {
        const fs::path p = silhouette_path(capture.takes[item.take].name, c, item.frame);
        std::error_code ec;
        if (!fs::is_regular_file(p, ec)) {
          throw InputError(fmt::format("segment --finish: {} is missing (take {} camera {} frame "
                                       "{}): its job has not run or failed",
                                       p.string(), capture.takes[item.take].name,
                                       cameras[c].name, item.frame));
        }
      }
    }
  }

  const MethodChoice choice = choose_method(session.root(), options.method);
  log::info("method {} ({})", choice.method, choice.reason);
  nlohmann::json report;
  report["method"] = choice.method;
  report["reason"] = choice.reason;

  const ConsistencyCheck consistency(cameras);
  if (!consistency.usable()) {
    log::info("no cross-camera check: {} camera(s) share too little of the volume",
              cameras.size());
  }

  // The per-camera models (the --finish job learns them again for the report).
  std::vector<Backdrop> backdrops(cameras.size());
  std::vector<KeyModel> keys(cameras.size());
  std::vector<PlateModel> plates(cameras.size());
  bool shadow_floor = false;  // plate: shadows only on the floor around the rig's centre
  if (choice.method == "chroma") {
    const auto samples = model_samples(capture, options.model_frames);
    tbb::parallel_for(std::size_t{0}, cameras.size(), [&](std::size_t c) {
      std::vector<cv::Mat> frames, maps;
      for (const auto& [t, f] : samples) {
        frames.push_back(read_capture_image(session, cameras[c], capture.takes[t].name, f));
      }
      backdrops[c] = learn_backdrop(frames, cameras[c].name);
      for (const cv::Mat& frame : frames) {
        maps.push_back(keyness(frame, backdrops[c], options.key_offset));
      }
      keys[c] = learn_key(maps);
    });
    for (std::size_t c = 0; c < cameras.size(); ++c) {
      const Backdrop& b = backdrops[c];
      log::info("camera {}: backdrop RGB ({:.0f}, {:.0f}, {:.0f}), hue {:.1f} deg, {:.0f}% of the "
                "pixels; keyness < {:.3f} is the performer, > {:.3f} the backdrop (learned from "
                "{} frames)", cameras[c].name, b.rgb[0], b.rgb[1], b.rgb[2], b.hue_deg,
                100 * b.fraction, keys[c].foreground_below, keys[c].backdrop_above,
                samples.size());
      report["backdrop"][cameras[c].name] = {{"rgb", {b.rgb[0], b.rgb[1], b.rgb[2]}},
                                             {"hue_deg", b.hue_deg},
                                             {"fraction", b.fraction}};
      report["key"][cameras[c].name] = {{"foreground_below", keys[c].foreground_below},
                                        {"backdrop_above", keys[c].backdrop_above}};
    }
  } else if (choice.method == "plate") {
    // The performer's shadows fall on the floor (z = 0) around where the cameras look; without
    // a floor below that point (it lies at or under z = 0) they may be anywhere.
    shadow_floor = consistency.has_aim() && consistency.aim_centre().z() > 0;
    if (shadow_floor) {
      log::info("shadows only on the floor within {:.3g} m of ({:.3g}, {:.3g})",
                kShadowReach * consistency.aim_reach(), consistency.aim_centre().x(),
                consistency.aim_centre().y());
    } else {
      log::info("shadows anywhere: the cameras do not look at a point above the floor z = 0");
    }
    tbb::parallel_for(std::size_t{0}, cameras.size(), [&](std::size_t c) {
      plates[c] = learn_plate(read_plates(session, cameras[c]), cameras[c].name);
      if (shadow_floor) {
        plates[c].shadow_region = floor_shadow_region(cameras[c], consistency.aim_centre(),
                                                      kShadowReach * consistency.aim_reach());
      }
    });
    for (std::size_t c = 0; c < cameras.size(); ++c) {
      log::info("camera {}: background model from {} plate(s), noise {:.2f} grey levels",
                cameras[c].name, plates[c].plates, plates[c].sigma);
      report["plates"][cameras[c].name] = {{"count", plates[c].plates},
                                           {"noise_sigma", plates[c].sigma}};
    }
  }

  if (!args.finish) {
    std::uintmax_t pixels = 0;  // one 8-bit mask per camera and frame, uncompressed at most
    for (const Camera& cam : cameras) {
      pixels += static_cast<std::uintmax_t>(cam.intrinsics.width) * cam.intrinsics.height;
    }
    require_free_space(out_dir, items.size() * pixels,
                       fmt::format("segment's masks of {} frames of {} cameras", items.size(),
                                   cameras.size()));
  }
  const std::size_t nc = cameras.size();
  std::vector<double> fractions(items.size() * nc, 0.0), explained(items.size() * nc, -1.0);
  log::Progress progress(args.finish ? "checking silhouettes" : "segmenting frames",
                         items.size());
  tbb::parallel_for(std::size_t{0}, items.size(), [&](std::size_t i) {
    const Item& item = items[i];
    const std::string& take = capture.takes[item.take].name;
    std::vector<cv::Mat> masks(nc), doubtful(nc);
    for (std::size_t c = 0; c < nc; ++c) {
      const fs::path path = silhouette_path(take, c, item.frame);
      cv::Mat& mask = masks[c];
      if (args.finish) {
        mask = read_image(path, cv::IMREAD_GRAYSCALE);
      } else if (choice.method == "masks") {
        mask = read_supplied_mask(mask_path(take, c, item.frame), cameras[c].name,
                                  cameras[c].intrinsics.width, cameras[c].intrinsics.height,
                                  item.frame);
      } else {
        const cv::Mat image = read_capture_image(session, cameras[c], take, item.frame);
        mask = choice.method == "plate"
                   ? plate_silhouette(image, plates[c], options, &doubtful[c])
                   : key_silhouette(image, backdrops[c], keys[c], options);
      }
    }
    // Plate with shadows anywhere: what one camera took for shadow, others may see as the
    // performer. Not with shadows only on the floor: there the coarse hull cannot tell the
    // shadow between the feet from the feet (room studio: segment.iou_mean 0.932 with, 0.950
    // without).
    if (!args.finish && choice.method == "plate" && !shadow_floor) {
      consistency.recover(masks, doubtful);
      for (cv::Mat& mask : masks) clean_up(mask, options);
    }
    for (std::size_t c = 0; c < nc; ++c) {
      const cv::Mat& mask = masks[c];
      if (!args.finish) {
        write_image_atomic(silhouette_path(take, c, item.frame), mask,
                           {cv::IMWRITE_PNG_COMPRESSION, 1});
      }
      fractions[i * nc + c] = cv::countNonZero(mask) / static_cast<double>(mask.total());
    }
    const std::vector<double> e = consistency.explained(masks);
    std::copy(e.begin(), e.end(), explained.begin() + static_cast<std::ptrdiff_t>(i * nc));
    progress.step();
  });

  // Summed and warned in frame order, so the report does not depend on the threads or the
  // job split.
  std::vector<std::vector<Coverage>> coverage(capture.takes.size(), std::vector<Coverage>(nc));
  std::vector<std::vector<Explained>> explained_sum(capture.takes.size(),
                                                    std::vector<Explained>(nc));
  std::vector<Warning> warnings;
  for (std::size_t i = 0; i < items.size(); ++i) {
    const std::string& take = capture.takes[items[i].take].name;
    for (std::size_t c = 0; c < nc; ++c) {
      const double fraction = fractions[i * nc + c];
      Coverage& cov = coverage[items[i].take][c];
      cov.sum += fraction;
      cov.min = std::min(cov.min, fraction);
      cov.max = std::max(cov.max, fraction);
      cov.frames += 1;
      cov.empty += fraction == 0;
      if (fraction < options.warn_foreground_min || fraction > options.warn_foreground_max) {
        warnings.push_back(
            {take, cameras[c].name, items[i].frame, "foreground_fraction", fraction,
             fmt::format("take {} camera {} frame {}: foreground covers {:.2f}% of the image, "
                         "outside [{:.2f}%, {:.2f}%]: check the segmentation or whether the "
                         "camera sees the volume",
                         take, cameras[c].name, items[i].frame, 100 * fraction,
                         100 * options.warn_foreground_min, 100 * options.warn_foreground_max)});
      }
      const double e = explained[i * nc + c];
      if (e < 0) continue;
      Explained& ex = explained_sum[items[i].take][c];
      ex.sum += e;
      ex.min = std::min(ex.min, e);
      ex.frames += 1;
      if (e < kMinExplained) {
        warnings.push_back(
            {take, cameras[c].name, items[i].frame, "inconsistent", e,
             fmt::format("take {} camera {} frame {}: only {:.0f}% of the silhouette is seen by "
                         "the other cameras (their visual hull): the segmentation took "
                         "background, or the calibration is off",
                         take, cameras[c].name, items[i].frame, 100 * e)});
      }
    }
  }
  for (std::size_t w = 0; w < warnings.size() && w < kMaxLoggedWarnings; ++w) {
    log::warn("{}", warnings[w].message);
  }
  if (warnings.size() > kMaxLoggedWarnings) {
    log::warn("... and {} more warnings about silhouettes (segment/report.json lists them)",
              warnings.size() - kMaxLoggedWarnings);
  }
  if (!warnings.empty()) {
    log::warn("{} warning(s) about {} silhouettes: the segmentation may have failed",
              warnings.size(), items.size() * nc);
  }

  // Per take and camera foreground fraction and consistency, so a bad key is visible at a glance.
  for (std::size_t t = 0; t < capture.takes.size(); ++t) {
    for (std::size_t c = 0; c < nc; ++c) {
      const Coverage& cov = coverage[t][c];
      if (cov.frames == 0) continue;
      report["foreground_fraction"][capture.takes[t].name][cameras[c].name] = {
          {"mean", cov.sum / cov.frames}, {"min", cov.min}, {"max", cov.max},
          {"frames", cov.frames}, {"empty_frames", cov.empty}};
      const Explained& ex = explained_sum[t][c];
      if (ex.frames == 0) continue;
      report["explained"][capture.takes[t].name][cameras[c].name] = {
          {"mean", ex.sum / ex.frames}, {"min", ex.min}, {"frames", ex.frames}};
    }
  }
  nlohmann::json list = nlohmann::json::array();
  for (const Warning& w : warnings) {
    list.push_back({{"take", w.take}, {"camera", w.camera}, {"frame", w.frame},
                    {"kind", w.kind}, {"value", w.value}, {"message", w.message}});
  }
  report["warning_count"] = warnings.size();
  report["warnings"] = list;
  // A job of a split run leaves the reports to the --finish job (which sees every frame).
  if (args.selection.whole()) {
    write_file_atomic(out_dir / "report.json", report.dump(1) + "\n");
    YAML::Emitter used;
    used << to_yaml(options);
    write_file_atomic(out_dir / "options.yaml", std::string(used.c_str()) + "\n");
  }
}

}  // namespace fourd::segment
