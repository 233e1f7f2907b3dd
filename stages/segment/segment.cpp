#include "stages/segment/segment.h"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <nlohmann/json.hpp>
#include <numbers>
#include <opencv2/imgproc.hpp>

#include "pipeline/core/error.h"
#include "pipeline/core/image_io.h"

namespace fourd::segment {

void SegmentOptions::check() const {
  if (method != "auto" && method != "chroma" && method != "plate" && method != "masks") {
    throw ConfigError(
        fmt::format("method '{}': expected auto, chroma, plate or masks", method));
  }
  if (warn_foreground_min > warn_foreground_max) {
    throw ConfigError("warn_foreground_min must not exceed warn_foreground_max");
  }
}

// ---- chroma ---------------------------------------------------------------------------------

namespace {

// The chroma plane (orthogonal to grey) in RGB: e1 towards red, e2 towards green minus blue.
const cv::Vec3d kChromaE1(2 / std::sqrt(6.0), -1 / std::sqrt(6.0), -1 / std::sqrt(6.0));
const cv::Vec3d kChromaE2(0, 1 / std::sqrt(2.0), -1 / std::sqrt(2.0));
const cv::Vec3d kGrey(1 / std::sqrt(3.0), 1 / std::sqrt(3.0), 1 / std::sqrt(3.0));

// A pixel counts towards the backdrop's hue when it is saturated (its chroma at least this
// fraction of the largest a pixel of its brightness can have: skin is about 0.3, chroma screens
// 0.7) and bright enough for its hue to be more than noise [8-bit levels].
constexpr double kMinSaturation = 0.4;
constexpr double kMinBrightness = 24;
// The backdrop's hue: the histogram's mode (1-degree bins, smoothed over kHueSmooth degrees
// either side); its pixels those within kHueWindow degrees of it.
constexpr int kHueSmooth = 4;
constexpr double kHueWindow = 20;
// Below this fraction of the sampled pixels, no colour is the backdrop's: the studio has no
// chroma screen, or the camera sees mostly something else.
constexpr double kMinBackdropFraction = 0.25;
// A learned hue within this of a primary (red, green, blue) is keyed along the primary.
constexpr double kHueSnap = 8;
// Pixels sampled for the hue: every kHueStride-th of every kHueStride-th row (a screen is large).
constexpr int kHueStride = 2;

double hue_of(const cv::Vec3d& rgb) {
  double h = std::atan2(rgb.dot(kChromaE2), rgb.dot(kChromaE1)) * 180 / std::numbers::pi;
  return h < 0 ? h + 360 : h;
}

}  // namespace

cv::Vec3d chroma_direction(double hue_deg) {
  const double a = hue_deg * std::numbers::pi / 180;
  return std::cos(a) * kChromaE1 + std::sin(a) * kChromaE2;
}

Backdrop learn_backdrop(const std::vector<cv::Mat>& frames, const std::string& camera) {
  std::vector<double> hist(360, 0.0);
  std::size_t total = 0;
  const double max_chroma = std::sqrt(2.0 / 3.0);  // |chroma| of a pure primary of brightness 1
  auto for_saturated = [&](auto&& f) {
    for (const cv::Mat& frame : frames) {
      CV_Assert(frame.type() == CV_8UC3);
      for (int r = 0; r < frame.rows; r += kHueStride) {
        const cv::Vec3b* p = frame.ptr<cv::Vec3b>(r);
        for (int c = 0; c < frame.cols; c += kHueStride) {
          const cv::Vec3d rgb(p[c][2], p[c][1], p[c][0]);
          const double bright = std::max({rgb[0], rgb[1], rgb[2]});
          if (bright < kMinBrightness) continue;
          const double x = rgb.dot(kChromaE1), y = rgb.dot(kChromaE2);
          if (std::hypot(x, y) < kMinSaturation * max_chroma * bright) continue;
          f(rgb);
        }
      }
    }
  };
  for (const cv::Mat& frame : frames) {
    total += static_cast<std::size_t>((frame.rows + kHueStride - 1) / kHueStride) *
             ((frame.cols + kHueStride - 1) / kHueStride);
  }
  for_saturated([&](const cv::Vec3d& rgb) { hist[static_cast<int>(hue_of(rgb)) % 360] += 1; });
  std::vector<double> smooth(360, 0.0);
  for (int i = 0; i < 360; ++i) {
    for (int k = -kHueSmooth; k <= kHueSmooth; ++k) smooth[i] += hist[(i + k + 360) % 360];
  }
  const int mode = static_cast<int>(std::max_element(smooth.begin(), smooth.end()) - smooth.begin());
  const double mode_hue = mode + 0.5;
  cv::Vec3d chroma_sum(0, 0, 0), rgb_sum(0, 0, 0);
  std::size_t count = 0;
  for_saturated([&](const cv::Vec3d& rgb) {
    if (std::abs(std::remainder(hue_of(rgb) - mode_hue, 360.0)) > kHueWindow) return;
    chroma_sum += rgb.dot(kChromaE1) * kChromaE1 + rgb.dot(kChromaE2) * kChromaE2;
    rgb_sum += rgb;
    ++count;
  });
  Backdrop b;
  b.fraction = total ? static_cast<double>(count) / total : 0.0;
  if (count == 0 || b.fraction < kMinBackdropFraction) {
    throw InputError(fmt::format(
        "camera {}: no backdrop colour: the most common saturated hue ({:.0f} deg) covers {:.1f}% "
        "of {} sampled frames, under the {:.0f}% a chroma screen covers; not a chroma studio? "
        "Give plates of the empty studio (plates/<camera>/000000.png) or masks, or set "
        "stages.segment.method",
        camera, mode_hue, 100 * b.fraction, frames.size(), 100 * kMinBackdropFraction));
  }
  b.direction = chroma_sum / cv::norm(chroma_sum);
  b.hue_deg = hue_of(b.direction);
  // A screen near a primary is keyed along the primary: the classic key, whose wedge of keyed
  // hues ends at the two other primaries (on the default green studio, learned 126.5 deg, the
  // learned direction gave segment.iou_mean 0.9816 against 0.9820 along pure green).
  const double primary = 120 * std::round(b.hue_deg / 120);
  if (std::abs(b.hue_deg - primary) <= kHueSnap) b.direction = chroma_direction(primary);
  b.rgb = rgb_sum / static_cast<double>(count);
  return b;
}

cv::Mat keyness(const cv::Mat& bgr, const Backdrop& backdrop, double offset) {
  CV_Assert(bgr.type() == CV_8UC3);
  // u: the backdrop's chroma direction; v: the other direction of the chroma plane. In BGR.
  const cv::Vec3d u_rgb = backdrop.direction, v_rgb = kGrey.cross(u_rgb);
  const float a = static_cast<float>(std::sqrt(6.0) / 2), b = static_cast<float>(1 / std::sqrt(2.0));
  const float d = static_cast<float>(std::sqrt(6.0) / 3);
  const cv::Vec3f u(static_cast<float>(u_rgb[2]), static_cast<float>(u_rgb[1]),
                    static_cast<float>(u_rgb[0]));
  const cv::Vec3f v(static_cast<float>(v_rgb[2]), static_cast<float>(v_rgb[1]),
                    static_cast<float>(v_rgb[0]));
  const float off = static_cast<float>(offset);
  cv::Mat out(bgr.size(), CV_32F);
  for (int r = 0; r < bgr.rows; ++r) {
    const cv::Vec3b* in = bgr.ptr<cv::Vec3b>(r);
    float* o = out.ptr<float>(r);
    for (int c = 0; c < bgr.cols; ++c) {
      const cv::Vec3f col(in[c][0], in[c][1], in[c][2]);
      const float along = col.dot(u);
      const float excess = a * along - b * std::abs(col.dot(v));
      const float brightness = (col[0] + col[1] + col[2]) / 3 + d * along;
      o[c] = excess / (std::max(brightness, 0.f) + off);
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

cv::Mat key_silhouette(const cv::Mat& bgr, const Backdrop& backdrop, const KeyModel& key,
                       const SegmentOptions& options) {
  const cv::Mat k = keyness(bgr, backdrop, options.key_offset);
  const cv::Mat sure_fg = k < key.foreground_below, sure_bg = k > key.backdrop_above;
  // Without sure neighbours of both kinds: the midpoint of the sure thresholds decides.
  const cv::Mat midpoint = k < 0.5 * (key.foreground_below + key.backdrop_above);
  cv::Mat mask = matte_outline(bgr, sure_fg, sure_bg, cv::Mat(), midpoint, options.matte_radius);
  clean_up(mask, options);
  return mask;
}

cv::Mat matte_outline(const cv::Mat& bgr, const cv::Mat& sure_fg, const cv::Mat& sure_bg,
                      const cv::Mat& background, const cv::Mat& undecided_fg, int radius) {
  cv::Mat color, fg_f, bg_f, sum_fg, sum_bg, n_fg, n_bg;
  bgr.convertTo(color, CV_32FC3);
  sure_fg.convertTo(fg_f, CV_32F, 1.0 / 255);
  const cv::Size fg_window(2 * radius - 1, 2 * radius - 1);
  cv::Mat fg3;
  cv::merge(std::vector<cv::Mat>{fg_f, fg_f, fg_f}, fg3);
  cv::boxFilter(color.mul(fg3), sum_fg, CV_32F, fg_window, {-1, -1}, false);
  cv::boxFilter(fg_f, n_fg, CV_32F, fg_window, {-1, -1}, false);
  const bool known_bg = !background.empty();
  if (!known_bg) {
    sure_bg.convertTo(bg_f, CV_32F, 1.0 / 255);
    const cv::Size bg_window(2 * radius + 1, 2 * radius + 1);
    cv::Mat bg3;
    cv::merge(std::vector<cv::Mat>{bg_f, bg_f, bg_f}, bg3);
    cv::boxFilter(color.mul(bg3), sum_bg, CV_32F, bg_window, {-1, -1}, false);
    cv::boxFilter(bg_f, n_bg, CV_32F, bg_window, {-1, -1}, false);
  }
  cv::Mat mask(bgr.size(), CV_8U);
  for (int r = 0; r < bgr.rows; ++r) {
    const std::uint8_t* f = sure_fg.ptr<std::uint8_t>(r);
    const std::uint8_t* b = sure_bg.ptr<std::uint8_t>(r);
    const std::uint8_t* u = undecided_fg.ptr<std::uint8_t>(r);
    const cv::Vec3f* c = color.ptr<cv::Vec3f>(r);
    const cv::Vec3f* sf = sum_fg.ptr<cv::Vec3f>(r);
    const float* nf = n_fg.ptr<float>(r);
    const cv::Vec3f* sb = known_bg ? background.ptr<cv::Vec3f>(r) : sum_bg.ptr<cv::Vec3f>(r);
    const float* nb = known_bg ? nullptr : n_bg.ptr<float>(r);
    std::uint8_t* m = mask.ptr<std::uint8_t>(r);
    for (int x = 0; x < bgr.cols; ++x) {
      if (f[x]) {
        m[x] = 255;
      } else if (b[x]) {
        m[x] = 0;
      } else if (nf[x] > 0 && (known_bg || nb[x] > 0)) {
        const cv::Vec3f fg = sf[x] / nf[x], bg = known_bg ? sb[x] : sb[x] / nb[x];
        const cv::Vec3f d = fg - bg;
        const float dd = d.dot(d);
        const float alpha = dd > 1e-3f ? (c[x] - bg).dot(d) / dd : 0.f;
        m[x] = alpha >= 0.5f ? 255 : 0;
      } else {
        m[x] = u[x] ? 255 : 0;
      }
    }
  }
  return mask;
}

void clean_up(cv::Mat& mask, const SegmentOptions& options) {
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
}

// ---- masks ----------------------------------------------------------------------------------

cv::Mat read_supplied_mask(const std::filesystem::path& path, const std::string& camera,
                           int width, int height, int frame) {
  std::error_code ec;
  if (!std::filesystem::is_regular_file(path, ec)) {
    throw InputError(fmt::format("{}: missing: camera {} frame {} has no supplied mask",
                                 path.string(), camera, frame));
  }
  cv::Mat image = read_image(path, cv::IMREAD_UNCHANGED);
  if (image.depth() != CV_8U) {
    throw InputError(fmt::format("{}: camera {} frame {}: the mask is not 8-bit", path.string(),
                                 camera, frame));
  }
  if (image.cols != width || image.rows != height) {
    throw InputError(fmt::format(
        "{}: camera {} frame {}: the mask is {}x{}, the camera's images are {}x{}", path.string(),
        camera, frame, image.cols, image.rows, width, height));
  }
  if (image.channels() == 3) cv::cvtColor(image, image, cv::COLOR_BGR2GRAY);
  if (image.channels() == 4) cv::cvtColor(image, image, cv::COLOR_BGRA2GRAY);
  return image > 127;
}

// ---- method choice --------------------------------------------------------------------------

namespace {

bool has_subfolder(const std::filesystem::path& dir) {
  std::error_code ec;
  if (!std::filesystem::is_directory(dir, ec)) return false;
  for (const auto& e : std::filesystem::directory_iterator(dir, ec)) {
    if (e.is_directory() && e.path().filename().string().front() != '.') return true;
  }
  return false;
}

}  // namespace

MethodChoice choose_method(const std::filesystem::path& root, const std::string& requested) {
  if (requested != "auto") return {requested, "set by stages.segment.method"};
  if (has_subfolder(root / "plates")) {
    return {"plate", "auto: plates/ holds plates of the empty studio"};
  }
  if (has_subfolder(root / "masks")) return {"masks", "auto: masks/ holds supplied masks"};
  return {"chroma", "auto: no plates/ and no masks/, so the backdrop is keyed by its colour"};
}

}  // namespace fourd::segment
