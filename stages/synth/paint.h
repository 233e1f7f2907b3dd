#pragma once
// Painting helpers shared by the performer's clothing (clothing.h) and the quadruped's coat
// (quadruped.h): deterministic noise, colours, the key-colour wardrobe rule and the loop that
// paints a texture image. Internal to the synth stage.
#include <Eigen/Core>
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <functional>
#include <opencv2/core.hpp>
#include <optional>
#include <vector>

namespace fourd::synth::detail {

using Rgb = Eigen::Vector3d;  // linear-ish RGB in [0, 1]

// Angle of d around `axis`, measured from `front`, folded to [0, pi].
inline double folded_angle(const Eigen::Vector3d& d, const Eigen::Vector3d& axis, const Eigen::Vector3d& front) {
  const Eigen::Vector3d q = d - d.dot(axis) * axis;
  const Eigen::Vector3d side = axis.cross(front);
  return std::abs(std::atan2(q.dot(side), q.dot(front)));
}

// ---- Deterministic noise ----
inline std::uint64_t splitmix64(std::uint64_t x) {
  x += 0x9E3779B97F4A7C15ull;
  x = (x ^ (x >> 30)) * 0xBF58476D1CE4E5B9ull;
  x = (x ^ (x >> 27)) * 0x94D049BB133111EBull;
  return x ^ (x >> 31);
}

inline double lattice(std::int64_t x, std::int64_t y, std::uint64_t seed) {
  const std::uint64_t h = splitmix64(seed ^ splitmix64(static_cast<std::uint64_t>(x) * 0x632BE59BD9B4E019ull ^
                                                       static_cast<std::uint64_t>(y)));
  return static_cast<double>(h >> 11) * (2.0 / 9007199254740992.0) - 1.0;  // [-1, 1)
}

inline double fade(double t) { return t * t * t * (t * (t * 6 - 15) + 10); }

// Value noise in [-1, 1] with unit lattice spacing.
inline double value_noise(double x, double y, std::uint64_t seed) {
  const double fx = std::floor(x), fy = std::floor(y);
  const auto ix = static_cast<std::int64_t>(fx), iy = static_cast<std::int64_t>(fy);
  const double tx = fade(x - fx), ty = fade(y - fy);
  const double a = lattice(ix, iy, seed), b = lattice(ix + 1, iy, seed);
  const double c = lattice(ix, iy + 1, seed), d = lattice(ix + 1, iy + 1, seed);
  return (a + (b - a) * tx) * (1 - ty) + (c + (d - c) * tx) * ty;
}

// Three octaves, wavelength `scale` [m] for the first.
inline double fbm(double x, double y, double scale, std::uint64_t seed) {
  double sum = 0, amp = 0.6;
  for (int o = 0; o < 3; ++o) {
    sum += amp * value_noise(x / scale, y / scale, seed + static_cast<std::uint64_t>(o) * 7919u);
    scale *= 0.5;
    amp *= 0.5;
  }
  return sum;
}

inline double smoothstep(double e0, double e1, double x) {
  const double t = std::clamp((x - e0) / (e1 - e0), 0.0, 1.0);
  return t * t * (3 - 2 * t);
}

// Additive variation proportional to the colour plus a floor, so that dark cloth keeps
// texture that stereo can match.
inline Rgb vary(const Rgb& c, double n) { return (c + n * (0.6 * c + Rgb::Constant(0.07))).cwiseMax(0.0).cwiseMin(1.0); }

inline Rgb rgb(int r, int g, int b) { return Rgb(r, g, b) / 255.0; }

// Hue [deg] and saturation (HSV) of a colour.
inline double hue_deg(const Rgb& c) {
  const double hi = c.maxCoeff(), lo = c.minCoeff(), d = hi - lo;
  if (d <= 0) return 0;
  double h = c.x() == hi ? (c.y() - c.z()) / d : c.y() == hi ? 2 + (c.z() - c.x()) / d
                                                             : 4 + (c.x() - c.y()) / d;
  h *= 60;
  return h < 0 ? h + 360 : h;
}
inline double saturation(const Rgb& c) { return c.maxCoeff() > 0 ? 1 - c.minCoeff() / c.maxCoeff() : 0; }

// A garment a costume department keeps off a key-colour screen: a saturated colour within 40
// degrees of hue of the key (navy trousers before a blue screen). Greys, whites and blacks key
// cleanly against any screen.
inline bool near_key(const Rgb& c, const std::optional<Rgb>& key) {
  if (!key || saturation(c) < 0.3 || saturation(*key) < 0.3) return false;
  const double dh = std::abs(hue_deg(c) - hue_deg(*key));
  return std::min(dh, 360 - dh) < 40;
}

// `palette` without the colours near the key, in order (all of it when none is near).
template <std::size_t N>
inline std::vector<Rgb> wardrobe(const std::array<Rgb, N>& palette, const std::optional<Rgb>& key) {
  std::vector<Rgb> out;
  for (const Rgb& c : palette) {
    if (!near_key(c, key)) out.push_back(c);
  }
  return out;
}

// A size x size CV_8UC3 image (BGR, OpenCV order) of colour(u, v) at every texel's centre, with
// (0, 0) the bottom-left corner of the image (uv's OBJ convention).
cv::Mat paint_image(int size, const std::function<Rgb(double u, double v)>& colour);

}  // namespace fourd::synth::detail
