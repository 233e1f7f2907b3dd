#include "stages/segment/plate.h"

#include <algorithm>
#include <cmath>
#include <opencv2/imgproc.hpp>

#include "pipeline/core/error.h"

namespace fourd::segment {
namespace {

// A shadow of the key light leaves the ambient light: on the synthetic studio's floor 0.38 of
// the lit brightness, in real studios rarely darker than a third. Darker than this fraction of
// the plate is not a shadow. Every shade above it is, so dark clothes over a neutral background
// pass for shadow: on the synthetic room segment.iou_mean was 0.834 at 0.3, 0.852 at 0.34.
constexpr double kShadowDarkest = 0.35;
// Shadows are lit by light of a slightly different colour than the key's (sky, bounce): this
// fraction of the pixel's brightness is allowed off the plate's chromaticity.
constexpr double kChromaSlack = 0.01;
// Differences from the (gain-corrected, shadow-scaled) plate in units of the difference's noise:
// up to kSureBackground surely background, from kSureForeground surely the performer, between
// them decided by the matte. 3-channel noise off the brightness axis has two degrees of freedom:
// 1% of the background exceeds 3, 4e-6 exceeds 5.
constexpr double kSureBackground = 3.0;
constexpr double kSureForeground = 5.0;
// The gain is measured on pixels whose brightness ratio to the plate is within this of the
// median ratio (the performer and its shadows are not).
constexpr double kGainWindow = 0.08;
// Plate pixels darker than this (sum of B, G, R) say little about the gain.
constexpr double kGainMinLevel = 60;

// Median of a sample of positive values (in place).
double median(std::vector<float>& v) {
  if (v.empty()) return 1.0;
  auto mid = v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2);
  std::nth_element(v.begin(), mid, v.end());
  return *mid;
}

// Pixels where the frame hides the plate's texture: over a kTextureWindow window the plate's
// brightness spreads by more than kTextureSpread noise levels and the frame's correlates with
// it by less than kTextureCorrelation. Where they can tell, only the window's pixels that may
// be a shadow count (`shadow_coloured`, 0/1 CV_32F: darker than the plate by more than the
// noise, of its chromaticity): beside the performer the window holds performer pixels too,
// whose colour hides the pattern whether or not the floor under the pixel is in shadow, and
// the shadow at a shoe's sole or beside a leg was taken for the performer (plate studio
// recipe: false foreground 28.7k -> 23.4k px of the 160 validated silhouettes). They cannot
// tell when fewer than kTextureMinCount of them or a plate without texture under them (grey
// trousers over one stripe of a rug): then the whole window counts.
constexpr int kTextureWindow = 7;
constexpr double kTextureSpread = 4.0;
constexpr double kTextureCorrelation = 0.5;
constexpr double kTextureMinCount = 12;
cv::Mat shadow_texture_hidden(const cv::Mat& bgr, const cv::Mat& plate_mean, float sigma,
                              const cv::Mat& shadow_coloured) {
  cv::Mat f, b;
  cv::cvtColor(bgr, f, cv::COLOR_BGR2GRAY);
  f.convertTo(f, CV_32F);
  cv::cvtColor(plate_mean, b, cv::COLOR_BGR2GRAY);
  const cv::Size k(kTextureWindow, kTextureWindow);
  // Window sums over every pixel and over the shadow-coloured ones.
  struct Sums {
    cv::Mat n, f, b, ff, bb, fb;
  };
  auto window_sums = [&](const cv::Mat& w) {
    Sums s;
    const cv::Mat wf = w.mul(f), wb = w.mul(b);
    cv::boxFilter(w, s.n, CV_32F, k, {-1, -1}, false);
    cv::boxFilter(wf, s.f, CV_32F, k, {-1, -1}, false);
    cv::boxFilter(wb, s.b, CV_32F, k, {-1, -1}, false);
    cv::boxFilter(wf.mul(f), s.ff, CV_32F, k, {-1, -1}, false);
    cv::boxFilter(wb.mul(b), s.bb, CV_32F, k, {-1, -1}, false);
    cv::boxFilter(wf.mul(b), s.fb, CV_32F, k, {-1, -1}, false);
    return s;
  };
  const Sums all = window_sums(cv::Mat::ones(f.size(), CV_32F));
  const Sums shadow_only = window_sums(shadow_coloured);
  cv::Mat hidden = cv::Mat::zeros(bgr.size(), CV_8U);
  const float min_var = static_cast<float>(kTextureSpread * kTextureSpread) * sigma * sigma;
  // The correlation over the window's pixels in `s`: false where the plate has no texture.
  auto hides = [&](const Sums& s, int r, int c, bool* textured) {
    const float n = s.n.at<float>(r, c);
    const float mf = s.f.at<float>(r, c) / n, mb = s.b.at<float>(r, c) / n;
    const float vb = s.bb.at<float>(r, c) / n - mb * mb;
    *textured = vb >= min_var;
    if (!*textured) return false;
    const float vf = s.ff.at<float>(r, c) / n - mf * mf;
    const float cov = s.fb.at<float>(r, c) / n - mf * mb;
    return cov < kTextureCorrelation * std::sqrt(std::max(vf, 0.f) * vb);
  };
  for (int r = 0; r < bgr.rows; ++r) {
    for (int c = 0; c < bgr.cols; ++c) {
      bool textured = false;
      bool hidden_here = false;
      if (shadow_only.n.at<float>(r, c) >= kTextureMinCount) {
        hidden_here = hides(shadow_only, r, c, &textured);
      }
      if (!textured) hidden_here = hides(all, r, c, &textured);
      if (hidden_here) hidden.at<std::uint8_t>(r, c) = 255;
    }
  }
  return hidden;
}

// The frame's colours (CV_32FC3) and, per pixel, the sum and the count of the colours of the
// `inside` pixels (0/255) within 2 px: the performer's colour F beside an outline pixel.
struct InsideColour {
  cv::Mat color, sum, count;
};
InsideColour inside_colour(const cv::Mat& bgr, const cv::Mat& inside) {
  InsideColour out;
  cv::Mat inside_f, inside3;
  inside.convertTo(inside_f, CV_32F, 1.0 / 255);
  bgr.convertTo(out.color, CV_32FC3);
  cv::merge(std::vector<cv::Mat>{inside_f, inside_f, inside_f}, inside3);
  const cv::Size window(5, 5);
  cv::boxFilter(out.color.mul(inside3), out.sum, CV_32F, window, {-1, -1}, false);
  cv::boxFilter(inside_f, out.count, CV_32F, window, {-1, -1}, false);
  return out;
}

// The matte alpha of colour c under c = alpha F + (1 - alpha) B, into `alpha`; false (alpha
// untouched) where there is no F (n = 0 inside pixels near) or F and B are nearer than
// `min_contrast` (the alpha would be noise).
bool matte_alpha(const cv::Vec3f& c, const cv::Vec3f& f_sum, float n, const cv::Vec3f& b,
                 float min_contrast, float* alpha) {
  if (n <= 0) return false;
  const cv::Vec3f d = f_sum / n - b;
  const float dd = d.dot(d);
  if (dd < min_contrast * min_contrast) return false;
  *alpha = (c - b).dot(d) / dd;
  return true;
}

// An outline pixel is partly the performer and partly the plate, and against a contrasting plate
// it is kSureForeground noise levels off already at a small coverage: on the room studio the
// silhouettes came out a pixel wide all round (that ring: 93 % of the false foreground). Each
// pixel on the mask's outline is judged again by its matte alpha, F the mean colour of the
// mask's interior within 2 px and B the plate's, where F and B are at least `min_contrast`
// apart (nearer, the alpha is noise and the pixel stays).
void trim_outline(cv::Mat& mask, const cv::Mat& bgr, const cv::Mat& background, float min_contrast) {
  // The outline against the outside only: a hole's rim (performer pixels like the plate
  // behind them) is the matte's and the hole filling's business.
  std::vector<std::vector<cv::Point>> contours;
  cv::findContours(mask, contours, cv::RETR_EXTERNAL, cv::CHAIN_APPROX_NONE);
  cv::Mat solid = cv::Mat::zeros(mask.size(), CV_8U);
  cv::drawContours(solid, contours, -1, cv::Scalar(255), cv::FILLED);
  cv::Mat inside;
  cv::erode(solid, inside, cv::Mat());
  const InsideColour f = inside_colour(bgr, inside);
  for (int r = 0; r < mask.rows; ++r) {
    std::uint8_t* m = mask.ptr<std::uint8_t>(r);
    const std::uint8_t* in = inside.ptr<std::uint8_t>(r);
    const cv::Vec3f* c = f.color.ptr<cv::Vec3f>(r);
    const cv::Vec3f* s = f.sum.ptr<cv::Vec3f>(r);
    const float* n = f.count.ptr<float>(r);
    const cv::Vec3f* b = background.ptr<cv::Vec3f>(r);
    for (int x = 0; x < mask.cols; ++x) {
      float alpha = 1;
      if (!m[x] || in[x]) continue;
      if (matte_alpha(c[x], s[x], n[x], b[x], min_contrast, &alpha) && alpha < 0.5f) m[x] = 0;
    }
  }
}

// The outline by its coverage, from the neighbours' too. A mixed pixel's own alpha is noisy:
// a renderer's or a sensor's few samples of the edge, the performer's colour beside it only
// estimated. The outline is smooth at the scale of a pixel, so the coverage smoothed over
// kOutlineBlur px has its half level where the performer's edge is, and each pixel on the
// outline (either side, 8-adjacent to the other) goes by that: alpha under
// C = alpha F + (1 - alpha) B, B the plate's colour and F the mean of the mask's pixels within
// 2 px that are not on the outline, clamped to [0, 1]; the rest of the mask 1, outside 0. Only
// where F and B are at least `min_contrast` apart (nearer, the alpha is noise and the pixel
// stays). The synthetic studio renders an outline pixel from 4 samples; its own alpha at 0.5
// (trim_outline) left 44.5k px wrong within a pixel of the true outlines of the plate
// studio's 160 validated silhouettes, smoothed 40.5k (docs/segment.md).
// A pixel whose own alpha is within kClearAlpha of 0 or 1 is no mix and goes by its own: where
// the image's edges are sharp (one sample a pixel) the smoothing only rounds corners and thins
// limbs (import_plate_studio, 320x240: segment.iou_mean 0.9595 smoothing every outline pixel,
// 0.9645 so; the plate studio recipe 0.9714 and 0.9709).
constexpr double kOutlineBlur = 1.25;
constexpr float kClearAlpha = 0.1f;
void refine_outline(cv::Mat& mask, const cv::Mat& bgr, const cv::Mat& background, float min_contrast) {
  cv::Mat outside = mask == 0, near_outside, near_inside;
  const cv::Mat square = cv::getStructuringElement(cv::MORPH_RECT, {3, 3});
  cv::dilate(outside, near_outside, square);
  cv::dilate(mask, near_inside, square);
  const cv::Mat band = (mask & near_outside) | (outside & near_inside);
  const InsideColour f = inside_colour(bgr, mask & ~near_outside);
  cv::Mat coverage, decided = cv::Mat::zeros(mask.size(), CV_8U);
  mask.convertTo(coverage, CV_32F, 1.0 / 255);
  for (int r = 0; r < mask.rows; ++r) {
    const std::uint8_t* on = band.ptr<std::uint8_t>(r);
    const cv::Vec3f* c = f.color.ptr<cv::Vec3f>(r);
    const cv::Vec3f* s = f.sum.ptr<cv::Vec3f>(r);
    const float* n = f.count.ptr<float>(r);
    const cv::Vec3f* b = background.ptr<cv::Vec3f>(r);
    float* a = coverage.ptr<float>(r);
    std::uint8_t* dec = decided.ptr<std::uint8_t>(r);
    for (int x = 0; x < mask.cols; ++x) {
      float alpha = 0;
      if (!on[x] || !matte_alpha(c[x], s[x], n[x], b[x], min_contrast, &alpha)) continue;
      a[x] = std::clamp(alpha, 0.0f, 1.0f);
      dec[x] = 255;
    }
  }
  cv::Mat smoothed;
  cv::GaussianBlur(coverage, smoothed, cv::Size(0, 0), kOutlineBlur);
  for (int r = 0; r < mask.rows; ++r) {
    const std::uint8_t* dec = decided.ptr<std::uint8_t>(r);
    const float* own = coverage.ptr<float>(r);
    const float* a = smoothed.ptr<float>(r);
    std::uint8_t* m = mask.ptr<std::uint8_t>(r);
    for (int x = 0; x < mask.cols; ++x) {
      if (!dec[x]) continue;
      const bool mixed = own[x] > kClearAlpha && own[x] < 1 - kClearAlpha;
      m[x] = (mixed ? a[x] : own[x]) >= 0.5f ? 255 : 0;
    }
  }
}

}  // namespace

PlateModel learn_plate(const std::vector<cv::Mat>& plates, const std::string& camera) {
  if (plates.empty()) {
    throw InputError(fmt::format("camera {}: no plate of the empty studio", camera));
  }
  PlateModel model;
  model.plates = static_cast<int>(plates.size());
  model.mean = cv::Mat::zeros(plates[0].size(), CV_32FC3);
  for (const cv::Mat& p : plates) {
    if (p.size() != plates[0].size() || p.type() != CV_8UC3) {
      throw InputError(fmt::format("camera {}: plates of different sizes ({}x{} and {}x{})",
                                   camera, plates[0].cols, plates[0].rows, p.cols, p.rows));
    }
    cv::accumulate(p, model.mean);
  }
  model.mean /= static_cast<double>(plates.size());
  // Noise from the plates' spread about their mean (robustly: the median absolute deviation),
  // or with one plate from neighbouring pixels' differences (texture edges are few).
  std::vector<float> deviations;
  if (plates.size() >= 2) {
    const double n = static_cast<double>(plates.size());
    for (const cv::Mat& p : plates) {
      for (int r = 0; r < p.rows; r += 2) {
        const cv::Vec3b* pp = p.ptr<cv::Vec3b>(r);
        const cv::Vec3f* mm = model.mean.ptr<cv::Vec3f>(r);
        for (int c = 0; c < p.cols; c += 2) {
          for (int ch = 0; ch < 3; ++ch) deviations.push_back(std::abs(pp[c][ch] - mm[c][ch]));
        }
      }
    }
    model.sigma = median(deviations) / 0.6745 * std::sqrt(n / (n - 1));
  } else {
    const cv::Mat& p = plates[0];
    for (int r = 0; r < p.rows; r += 2) {
      const cv::Vec3b* pp = p.ptr<cv::Vec3b>(r);
      for (int c = 0; c + 1 < p.cols; c += 2) {
        for (int ch = 0; ch < 3; ++ch) deviations.push_back(std::abs(pp[c + 1][ch] - pp[c][ch]));
      }
    }
    model.sigma = median(deviations) / 0.6745 / std::sqrt(2.0);
  }
  model.sigma = std::max(model.sigma, 0.5);  // quantisation alone
  return model;
}

cv::Mat floor_shadow_region(const Camera& camera, const Eigen::Vector3d& centre, double radius) {
  const int w = camera.intrinsics.width, h = camera.intrinsics.height;
  cv::Mat region = cv::Mat::zeros(h, w, CV_8U);
  const double r2 = radius * radius;
  for (int y = 0; y < h; ++y) {
    std::uint8_t* out = region.ptr<std::uint8_t>(y);
    for (int x = 0; x < w; ++x) {
      const Ray ray = camera.unproject(Eigen::Vector2d(x + 0.5, y + 0.5));
      if (!(ray.direction.z() < 0) || !(ray.origin.z() > 0)) continue;
      const Eigen::Vector3d hit = ray.origin - (ray.origin.z() / ray.direction.z()) * ray.direction;
      if ((hit.head<2>() - centre.head<2>()).squaredNorm() <= r2) out[x] = 255;
    }
  }
  return region;
}

cv::Vec3d background_gain(const cv::Mat& bgr, const PlateModel& plate) {
  CV_Assert(bgr.type() == CV_8UC3 && bgr.size() == plate.mean.size());
  std::vector<float> ratios;
  auto for_pixels = [&](auto&& f) {
    for (int r = 0; r < bgr.rows; r += 2) {
      const cv::Vec3b* in = bgr.ptr<cv::Vec3b>(r);
      const cv::Vec3f* m = plate.mean.ptr<cv::Vec3f>(r);
      for (int c = 0; c < bgr.cols; c += 2) {
        const float level = m[c][0] + m[c][1] + m[c][2];
        if (level < kGainMinLevel) continue;
        f(in[c], m[c], (in[c][0] + in[c][1] + in[c][2]) / level);
      }
    }
  };
  for_pixels([&](const cv::Vec3b&, const cv::Vec3f&, float ratio) { ratios.push_back(ratio); });
  const double typical = median(ratios);
  cv::Vec3d frame_sum(0, 0, 0), plate_sum(0, 0, 0);
  for_pixels([&](const cv::Vec3b& f, const cv::Vec3f& m, float ratio) {
    if (std::abs(ratio / typical - 1) > kGainWindow) return;
    for (int ch = 0; ch < 3; ++ch) {
      frame_sum[ch] += f[ch];
      plate_sum[ch] += m[ch];
    }
  });
  cv::Vec3d gain(1, 1, 1);
  for (int ch = 0; ch < 3; ++ch) {
    if (plate_sum[ch] > 0) gain[ch] = frame_sum[ch] / plate_sum[ch];
  }
  return gain;
}

namespace {

// The brightness ratio of `col` to the plate's colour B (a shadow: below 1; 1 where B is black).
float brightness_ratio(const cv::Vec3f& col, const cv::Vec3f& B) {
  const float bb = B.dot(B);
  return bb > 1.0f ? col.dot(B) / bb : 1.0f;
}

// How far `col` is off the chromaticity of the plate's colour B (alpha: its brightness ratio
// to B), less the slack a shadow's differently coloured light takes.
float off_plate_chroma(const cv::Vec3f& col, const cv::Vec3f& B, float alpha) {
  return static_cast<float>(
      std::max(0.0, cv::norm(col - alpha * B) - kChromaSlack * alpha * std::sqrt(B.dot(B))));
}

// The noise of a frame's difference from the plates' mean: the noise of both.
float frame_noise(const PlateModel& plate) {
  return static_cast<float>(plate.sigma * std::sqrt(1.0 + 1.0 / std::max(1, plate.plates)));
}

}  // namespace

cv::Mat plate_silhouette(const cv::Mat& bgr, const PlateModel& plate,
                         const SegmentOptions& options, cv::Mat* shadow_like, cv::Mat* off_plate) {
  if (bgr.size() != plate.mean.size()) {
    throw InputError(fmt::format("frame of {}x{} against plates of {}x{}", bgr.cols, bgr.rows,
                                 plate.mean.cols, plate.mean.rows));
  }
  const cv::Vec3d g = background_gain(bgr, plate);
  const cv::Vec3f gain(static_cast<float>(g[0]), static_cast<float>(g[1]), static_cast<float>(g[2]));
  const float sigma = frame_noise(plate);
  cv::Mat background(bgr.size(), CV_32FC3);
  cv::Mat sure_fg(bgr.size(), CV_8U), sure_bg(bgr.size(), CV_8U), midpoint(bgr.size(), CV_8U);
  const float mid = static_cast<float>(0.5 * (kSureBackground + kSureForeground));
  cv::Mat shade_only = cv::Mat::zeros(bgr.size(), CV_8U), off = cv::Mat::zeros(bgr.size(), CV_8U);
  const bool shadows_anywhere = plate.shadow_region.empty();
  // A shadow darkens the plate's texture, which shows through it; the performer hides it. Per
  // pixel, the correlation of the frame's and the plate's brightness over a small window
  // (its pixels that may be shadow, where they suffice), where the plate has texture to
  // correlate (spread above the noise).
  cv::Mat shadow_coloured(bgr.size(), CV_32F);
  for (int r = 0; r < bgr.rows; ++r) {
    const cv::Vec3b* in = bgr.ptr<cv::Vec3b>(r);
    const cv::Vec3f* m = plate.mean.ptr<cv::Vec3f>(r);
    float* w = shadow_coloured.ptr<float>(r);
    for (int c = 0; c < bgr.cols; ++c) {
      const cv::Vec3f col(in[c][0], in[c][1], in[c][2]);
      const cv::Vec3f B = m[c].mul(gain);
      const float alpha = brightness_ratio(col, B);
      w[c] = off_plate_chroma(col, B, alpha) < kSureForeground * sigma &&
                     (1.0f - alpha) * std::sqrt(B.dot(B)) > kSureBackground * sigma
                 ? 1.0f : 0.0f;
    }
  }
  cv::Mat texture_hidden = shadow_texture_hidden(bgr, plate.mean, sigma, shadow_coloured);
  for (int r = 0; r < bgr.rows; ++r) {
    const std::uint8_t* hidden = texture_hidden.ptr<std::uint8_t>(r);
    const cv::Vec3b* in = bgr.ptr<cv::Vec3b>(r);
    const cv::Vec3f* m = plate.mean.ptr<cv::Vec3f>(r);
    const std::uint8_t* may_shade = shadows_anywhere ? nullptr : plate.shadow_region.ptr<std::uint8_t>(r);
    cv::Vec3f* bg = background.ptr<cv::Vec3f>(r);
    std::uint8_t *f = sure_fg.ptr<std::uint8_t>(r), *b = sure_bg.ptr<std::uint8_t>(r);
    std::uint8_t* u = midpoint.ptr<std::uint8_t>(r);
    for (int c = 0; c < bgr.cols; ++c) {
      const cv::Vec3f col(in[c][0], in[c][1], in[c][2]);
      const cv::Vec3f B = m[c].mul(gain);
      bg[c] = B;
      // Brightness ratio to the plate (a shadow: below 1) and the colour off its chromaticity.
      const float alpha = brightness_ratio(col, B);
      const float norm_b = std::sqrt(B.dot(B));
      const float darkest = (!may_shade || may_shade[c]) && !hidden[c]
                                ? static_cast<float>(kShadowDarkest) : 1.0f;
      const float shade = std::clamp(alpha, darkest, 1.0f);
      const float off_chroma = off_plate_chroma(col, B, alpha);
      const float off_brightness = std::abs(alpha - shade) * norm_b;
      const float d = std::max(off_chroma, off_brightness) / sigma;
      f[c] = d >= kSureForeground ? 255 : 0;
      b[c] = d <= kSureBackground ? 255 : 0;
      // Background only by the shadow rule: clearly darker than the plate.
      if (b[c] && (1.0f - alpha) * norm_b > kSureForeground * sigma) shade_only.at<std::uint8_t>(r, c) = 255;
      // Off the plate by more than the noise, shadow or not.
      if (std::max(off_chroma, std::abs(alpha - 1.0f) * norm_b) > kSureBackground * sigma) {
        off.at<std::uint8_t>(r, c) = 255;
      }
      u[c] = d > mid ? 255 : 0;
    }
  }
  cv::Mat mask = matte_outline(bgr, sure_fg, sure_bg, background, midpoint, options.matte_radius);
  const cv::Mat keyed = mask.clone();
  clean_up(mask, options);
  // The opening takes the steps of the outline's staircase too: the keyed pixels next to what
  // the clean-up kept are given back (speckles away from the performer stay away).
  cv::Mat grown;
  cv::dilate(mask, grown, cv::getStructuringElement(cv::MORPH_CROSS, {3, 3}));
  mask |= grown & keyed;
  trim_outline(mask, bgr, background, static_cast<float>(2 * kSureForeground) * sigma);
  if (shadow_like) *shadow_like = shade_only & (mask == 0);
  if (off_plate) *off_plate = off & (mask == 0);
  return mask;
}

void refine_plate_outline(cv::Mat& mask, const cv::Mat& bgr, const PlateModel& plate) {
  const cv::Vec3d g = background_gain(bgr, plate);
  cv::Mat background;
  cv::multiply(plate.mean, cv::Scalar(g[0], g[1], g[2]), background);
  const float sigma = frame_noise(plate);
  refine_outline(mask, bgr, background, static_cast<float>(2 * kSureForeground) * sigma);
}

}  // namespace fourd::segment
