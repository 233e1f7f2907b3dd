#include "stages/segment/segment.h"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <nlohmann/json.hpp>
#include <opencv2/imgproc.hpp>

#include "pipeline/core/capture.h"
#include "pipeline/core/colmap_model.h"
#include "pipeline/core/error.h"
#include "pipeline/core/files.h"
#include "pipeline/core/image_io.h"
#include "pipeline/core/log.h"

namespace fourd::segment {

cv::Mat keyness(const cv::Mat& bgr, double offset) {
  CV_Assert(bgr.type() == CV_8UC3);
  cv::Mat out(bgr.size(), CV_32F);
  for (int r = 0; r < bgr.rows; ++r) {
    const cv::Vec3b* in = bgr.ptr<cv::Vec3b>(r);
    float* o = out.ptr<float>(r);
    for (int c = 0; c < bgr.cols; ++c) {
      float b = in[c][0], g = in[c][1], red = in[c][2];
      o[c] = (g - std::max(red, b)) / (g + static_cast<float>(offset));
    }
  }
  return out;
}

namespace {

// Otsu's threshold over a histogram of keyness in [-1, 1].
double otsu_threshold(const std::vector<double>& hist) {
  const int bins = static_cast<int>(hist.size());
  double total = 0, sum = 0;
  for (int i = 0; i < bins; ++i) {
    total += hist[i];
    sum += i * hist[i];
  }
  double w0 = 0, sum0 = 0, best = -1;
  int best_bin = bins / 2;
  for (int i = 0; i < bins; ++i) {
    w0 += hist[i];
    sum0 += i * hist[i];
    double w1 = total - w0;
    if (w0 == 0 || w1 == 0) continue;
    double m0 = sum0 / w0, m1 = (sum - sum0) / w1;
    double between = w0 * w1 * (m0 - m1) * (m0 - m1);
    if (between > best) {
      best = between;
      best_bin = i;
    }
  }
  return (best_bin + 0.5) / (bins - 1) * 2.0 - 1.0;
}

double bin_value(int bin, int bins) { return (bin + 0.5) / (bins - 1) * 2.0 - 1.0; }

}  // namespace

KeyModel learn_key(const std::vector<cv::Mat>& keyness_maps) {
  constexpr int kBins = 256;
  std::vector<double> hist(kBins, 0.0);
  for (const cv::Mat& k : keyness_maps) {
    for (int r = 0; r < k.rows; ++r) {
      const float* p = k.ptr<float>(r);
      for (int c = 0; c < k.cols; ++c) {
        int bin = static_cast<int>((std::clamp(p[c], -1.f, 1.f) + 1.f) * 0.5f * (kBins - 1) + 0.5f);
        hist[bin] += 1;
      }
    }
  }
  KeyModel key;
  key.foreground_below = otsu_threshold(hist);
  // Surely backdrop: above the 2nd percentile of the backdrop class, so that shadows and
  // darker corners of the screen still count, but outline pixels mixed with the performer don't.
  double backdrop = 0;
  int first = 0;
  while (first < kBins && bin_value(first, kBins) <= key.foreground_below) ++first;
  for (int i = first; i < kBins; ++i) backdrop += hist[i];
  double acc = 0;
  key.backdrop_above = key.foreground_below;
  for (int i = first; i < kBins; ++i) {
    acc += hist[i];
    if (acc >= 0.02 * backdrop) {
      key.backdrop_above = std::max(key.foreground_below, bin_value(i, kBins));
      break;
    }
  }
  return key;
}

cv::Mat key_silhouette(const cv::Mat& bgr, const KeyModel& key, const SegmentOptions& options) {
  const cv::Mat k = keyness(bgr, options.key_offset);
  cv::Mat sure_fg = k < key.foreground_below, sure_bg = k > key.backdrop_above;
  // Colours mix linearly at the outline: C = alpha F + (1 - alpha) B. With B and F the mean
  // colours of the sure backdrop and sure performer near the pixel, alpha is the projection
  // of C - B onto F - B.
  cv::Mat color, fg_f, bg_f, sum_fg, sum_bg, n_fg, n_bg;
  bgr.convertTo(color, CV_32FC3);
  sure_fg.convertTo(fg_f, CV_32F, 1.0 / 255);
  sure_bg.convertTo(bg_f, CV_32F, 1.0 / 255);
  const cv::Size fg_window(2 * options.matte_radius - 1, 2 * options.matte_radius - 1);
  const cv::Size bg_window(2 * options.matte_radius + 1, 2 * options.matte_radius + 1);
  cv::Mat fg3, bg3;
  cv::merge(std::vector<cv::Mat>{fg_f, fg_f, fg_f}, fg3);
  cv::merge(std::vector<cv::Mat>{bg_f, bg_f, bg_f}, bg3);
  cv::boxFilter(color.mul(fg3), sum_fg, CV_32F, fg_window, {-1, -1}, false);
  cv::boxFilter(color.mul(bg3), sum_bg, CV_32F, bg_window, {-1, -1}, false);
  cv::boxFilter(fg_f, n_fg, CV_32F, fg_window, {-1, -1}, false);
  cv::boxFilter(bg_f, n_bg, CV_32F, bg_window, {-1, -1}, false);
  cv::Mat mask(bgr.size(), CV_8U);
  for (int r = 0; r < bgr.rows; ++r) {
    const std::uint8_t* f = sure_fg.ptr<std::uint8_t>(r);
    const std::uint8_t* b = sure_bg.ptr<std::uint8_t>(r);
    const cv::Vec3f* c = color.ptr<cv::Vec3f>(r);
    const cv::Vec3f *sf = sum_fg.ptr<cv::Vec3f>(r), *sb = sum_bg.ptr<cv::Vec3f>(r);
    const float *nf = n_fg.ptr<float>(r), *nb = n_bg.ptr<float>(r);
    const float* kk = k.ptr<float>(r);
    std::uint8_t* m = mask.ptr<std::uint8_t>(r);
    for (int x = 0; x < bgr.cols; ++x) {
      if (f[x]) {
        m[x] = 255;
      } else if (b[x]) {
        m[x] = 0;
      } else if (nf[x] > 0 && nb[x] > 0) {
        const cv::Vec3f fg = sf[x] / nf[x], bg = sb[x] / nb[x];
        const cv::Vec3f d = fg - bg;
        const float dd = d.dot(d);
        const float alpha = dd > 1e-3f ? (c[x] - bg).dot(d) / dd : 0.f;
        m[x] = alpha >= 0.5f ? 255 : 0;
      } else {
        // No sure neighbours of both kinds: fall back to the midpoint of the sure thresholds.
        m[x] = kk[x] < 0.5 * (key.foreground_below + key.backdrop_above) ? 255 : 0;
      }
    }
  }
  if (options.open_radius > 0) {
    cv::Mat kernel = cv::getStructuringElement(
        cv::MORPH_ELLIPSE, cv::Size(2 * options.open_radius + 1, 2 * options.open_radius + 1));
    cv::morphologyEx(mask, mask, cv::MORPH_OPEN, kernel);
  }
  // Keep the performer: the largest component and any comparable ones (a detached hand).
  cv::Mat labels, stats, centroids;
  int n = cv::connectedComponentsWithStats(mask, labels, stats, centroids, 8, CV_32S);
  int largest = 0;
  for (int i = 1; i < n; ++i) largest = std::max(largest, stats.at<int>(i, cv::CC_STAT_AREA));
  std::vector<std::uint8_t> keep(n, 0);
  for (int i = 1; i < n; ++i) {
    keep[i] = stats.at<int>(i, cv::CC_STAT_AREA) >= options.min_component_fraction * largest;
  }
  for (int r = 0; r < mask.rows; ++r) {
    const int* l = labels.ptr<int>(r);
    std::uint8_t* m = mask.ptr<std::uint8_t>(r);
    for (int c = 0; c < mask.cols; ++c) m[c] = keep[l[c]] ? 255 : 0;
  }
  // Fill small enclosed holes (key noise inside clothing); large ones are real (arm gaps).
  cv::Mat background;
  cv::bitwise_not(mask, background);
  n = cv::connectedComponentsWithStats(background, labels, stats, centroids, 4, CV_32S);
  const double max_hole = options.max_hole_fraction * mask.total();
  for (int i = 1; i < n; ++i) {
    int x = stats.at<int>(i, cv::CC_STAT_LEFT), y = stats.at<int>(i, cv::CC_STAT_TOP);
    int w = stats.at<int>(i, cv::CC_STAT_WIDTH), h = stats.at<int>(i, cv::CC_STAT_HEIGHT);
    bool touches_border = x == 0 || y == 0 || x + w == mask.cols || y + h == mask.rows;
    if (!touches_border && stats.at<int>(i, cv::CC_STAT_AREA) <= max_hole) {
      mask.setTo(255, labels == i);
    }
  }
  return mask;
}

namespace {

struct Item {
  std::size_t take;
  int frame;
};

struct Coverage {
  double sum = 0, min = 1, max = 0;
  int frames = 0, empty = 0;
};

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

  // Learn the key per camera from frames spread over every take.
  std::vector<KeyModel> keys(cameras.size());
  {
    std::vector<std::pair<std::size_t, int>> samples;
    std::size_t total = 0;
    for (const auto& t : capture.takes) total += t.frame_count;
    for (int i = 0; i < options.model_frames; ++i) {
      std::size_t global = (2 * i + 1) * total / (2 * options.model_frames);
      for (std::size_t t = 0; t < capture.takes.size(); ++t) {
        if (global < static_cast<std::size_t>(capture.takes[t].frame_count)) {
          samples.emplace_back(t, static_cast<int>(global));
          break;
        }
        global -= capture.takes[t].frame_count;
      }
    }
    tbb::parallel_for(std::size_t{0}, cameras.size(), [&](std::size_t c) {
      std::vector<cv::Mat> maps;
      for (const auto& [t, f] : samples) {
        maps.push_back(keyness(read_capture_image(session, cameras[c], capture.takes[t].name, f),
                               options.key_offset));
      }
      keys[c] = learn_key(maps);
    });
    for (std::size_t c = 0; c < cameras.size(); ++c) {
      log::info("camera {}: keyness < {:.3f} is the performer, > {:.3f} the backdrop (learned "
                "from {} frames)", cameras[c].name, keys[c].foreground_below,
                keys[c].backdrop_above, samples.size());
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
  std::vector<std::vector<Coverage>> coverage(capture.takes.size(),
                                              std::vector<Coverage>(cameras.size()));
  std::vector<double> fractions(items.size() * cameras.size(), 0.0);
  log::Progress progress(args.finish ? "summarising silhouettes" : "segmenting frames",
                         items.size());
  tbb::parallel_for(std::size_t{0}, items.size(), [&](std::size_t i) {
    const Item& item = items[i];
    const std::string& take = capture.takes[item.take].name;
    for (std::size_t c = 0; c < cameras.size(); ++c) {
      const fs::path path = silhouette_path(take, c, item.frame);
      cv::Mat mask;
      if (args.finish) {
        mask = read_image(path, cv::IMREAD_GRAYSCALE);
      } else {
        mask = key_silhouette(read_capture_image(session, cameras[c], take, item.frame), keys[c],
                              options);
      }
      double fraction = cv::countNonZero(mask) / static_cast<double>(mask.total());
      if (!args.finish &&
          (fraction < options.warn_foreground_min || fraction > options.warn_foreground_max)) {
        log::warn("take {} camera {} frame {}: foreground covers {:.2f}% of the image — check "
                  "the key or whether the camera sees the volume",
                  take, cameras[c].name, item.frame, 100 * fraction);
      }
      if (!args.finish) write_image_atomic(path, mask, {cv::IMWRITE_PNG_COMPRESSION, 1});
      fractions[i * cameras.size() + c] = fraction;
    }
    progress.step();
  });
  // Summed in frame order, so the report does not depend on the threads or the job split.
  for (std::size_t i = 0; i < items.size(); ++i) {
    for (std::size_t c = 0; c < cameras.size(); ++c) {
      const double fraction = fractions[i * cameras.size() + c];
      Coverage& cov = coverage[items[i].take][c];
      cov.sum += fraction;
      cov.min = std::min(cov.min, fraction);
      cov.max = std::max(cov.max, fraction);
      cov.frames += 1;
      cov.empty += fraction == 0;
    }
  }

  // Per take and camera foreground fraction, so a bad key is visible at a glance.
  nlohmann::json report;
  for (std::size_t c = 0; c < cameras.size(); ++c) {
    report["key"][cameras[c].name] = {{"foreground_below", keys[c].foreground_below},
                                      {"backdrop_above", keys[c].backdrop_above}};
  }
  for (std::size_t t = 0; t < capture.takes.size(); ++t) {
    for (std::size_t c = 0; c < cameras.size(); ++c) {
      const Coverage& cov = coverage[t][c];
      if (cov.frames == 0) continue;
      report["foreground_fraction"][capture.takes[t].name][cameras[c].name] = {
          {"mean", cov.sum / cov.frames}, {"min", cov.min}, {"max", cov.max},
          {"frames", cov.frames}, {"empty_frames", cov.empty}};
    }
  }
  // A job of a split run leaves the reports to the --finish job (which sees every frame).
  if (args.selection.whole()) {
    write_file_atomic(out_dir / "report.json", report.dump(1) + "\n");
    YAML::Emitter used;
    used << to_yaml(options);
    write_file_atomic(out_dir / "options.yaml", std::string(used.c_str()) + "\n");
  }
}

}  // namespace fourd::segment
