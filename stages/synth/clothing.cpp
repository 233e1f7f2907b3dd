#include "stages/synth/clothing.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <optional>
#include <vector>

#include "stages/synth/paint.h"

namespace fourd::synth::detail {
namespace {

using Eigen::Vector3d;

// ---- Atlas layout (u to the right, v up) ----
// Rows are height above the floor for the torso, legs and arms (arms: length along the arm,
// starting at the shoulder's row), so junctions meet at the same rows.
constexpr double kTopNominal = 1.76;  // nominal top of the atlas rows [m]
constexpr double kRow0 = 0.01, kRowSpan = 0.98;
constexpr double kTorsoU0 = 0.01, kTorsoDu = 0.48;
constexpr double kLegU0 = 0.51, kLegDu = 0.23;
constexpr double kArmU0 = 0.76, kArmDu = 0.23;
constexpr double kFootU0 = 0.01, kFootDu = 0.48, kFootV0 = 0.01, kFootDv = 0.34;
constexpr double kFootTorsoSplitV = 0.375;  // below: feet chart, above: torso chart (u < 0.5)
// The skirt's chart sits in the legs' column above the rows they use (hips at about v 0.57):
// v from kSkirtV0 (hem) to kSkirtV0 + kSkirtDv (waist). With a skirt, the texels from
// kSkirtPaintV0 up in that column carry its colours, so sampling at the chart's border never
// reaches the legs'.
constexpr double kSkirtU0 = kLegU0, kSkirtDu = kLegDu, kSkirtV0 = 0.64, kSkirtDv = 0.35;
constexpr double kSkirtPaintV0 = 0.61;

double top(const BodyModel& body) { return kTopNominal * body.scale; }
double v_of_z(const BodyModel& body, double z) { return kRow0 + kRowSpan * z / top(body); }
double z_of_v(const BodyModel& body, double v) { return (v - kRow0) / kRowSpan * top(body); }

// ---- Clothing ----
struct Outfit {
  Rgb shirt, shirt2, trousers, skin, lips, hair, iris, shoes, sole, belt;
  int shirt_style = 0;       // 0 stripes, 1 plaid, 2 print, 3 dots
  double pattern_period = 0.04;  // [m]
  std::uint64_t seed = 0;
  Rgb skirt, skirt2;         // the skirt's cloth and its print, hem and waistband
};


Outfit choose_outfit(std::uint64_t seed, const std::optional<Rgb>& key) {
  // No greens anywhere: the default studio is chroma green. Other keys leave out their own hue.
  const std::array<Rgb, 12> all_shirts = {rgb(200, 40, 40),  rgb(40, 80, 190),   rgb(230, 120, 30),
                                      rgb(120, 50, 150), rgb(225, 190, 40),  rgb(230, 228, 222),
                                      rgb(140, 140, 148), rgb(30, 40, 95),   rgb(220, 110, 150),
                                      rgb(125, 25, 40),  rgb(120, 170, 220), rgb(40, 38, 42)};
  const std::array<Rgb, 6> all_trousers = {rgb(45, 65, 115), rgb(32, 32, 36),  rgb(95, 95, 100),
                                       rgb(185, 158, 112), rgb(100, 70, 45), rgb(38, 42, 75)};
  const std::array<Rgb, 6> skins = {rgb(240, 200, 170), rgb(225, 180, 145), rgb(200, 150, 110),
                                    rgb(165, 115, 80),  rgb(125, 85, 58),  rgb(92, 62, 46)};
  const std::array<Rgb, 6> hairs = {rgb(25, 20, 20),    rgb(60, 40, 25),  rgb(110, 75, 45),
                                    rgb(210, 180, 120), rgb(140, 60, 30), rgb(170, 165, 160)};
  const std::array<Rgb, 5> all_shoes = {rgb(25, 25, 28), rgb(225, 225, 225), rgb(90, 55, 35),
                                    rgb(170, 30, 35), rgb(40, 60, 140)};
  const std::vector<Rgb> shirts = wardrobe(all_shirts, key);
  const std::vector<Rgb> trousers = wardrobe(all_trousers, key);
  const std::vector<Rgb> shoes = wardrobe(all_shoes, key);
  std::uint64_t state = seed;
  auto pick = [&](std::size_t n) {
    state = splitmix64(state);
    return static_cast<std::size_t>(state % n);
  };
  Outfit o;
  o.seed = splitmix64(seed ^ 0xC1074E5ull);
  const std::size_t s1 = pick(shirts.size());
  o.shirt = shirts[s1];
  o.shirt2 = shirts[(s1 + 1 + pick(shirts.size() - 1)) % shirts.size()];
  // Trousers that stand apart from the shirt, so the waist is a visible edge.
  std::size_t t = pick(trousers.size());
  for (std::size_t k = 0; k < trousers.size() && (trousers[t] - o.shirt).norm() < 0.25; ++k) {
    t = (t + 1) % trousers.size();
  }
  o.trousers = trousers[t];
  o.skin = skins[pick(skins.size())];
  o.lips = o.skin.cwiseProduct(rgb(230, 150, 150));
  o.hair = hairs[pick(hairs.size())];
  o.iris = pick(2) ? rgb(60, 40, 25) : rgb(60, 90, 140);
  const std::size_t sh = pick(shoes.size());
  o.shoes = shoes[sh];
  o.sole = o.shoes == all_shoes[1] ? rgb(90, 90, 95) : rgb(230, 230, 228);  // white shoes
  o.belt = rgb(55, 35, 25);
  o.shirt_style = static_cast<int>(pick(4));
  o.pattern_period = 0.03 + 0.01 * static_cast<double>(pick(4));
  // The skirt, from a stream of its own (the rest of the outfit is what it was before skirts):
  // a colour apart from the shirt and the trousers, so its waist and hem are visible edges.
  std::uint64_t skirt_state = splitmix64(seed ^ 0x5C127ull);
  auto skirt_pick = [&](std::size_t n) {
    skirt_state = splitmix64(skirt_state);
    return static_cast<std::size_t>(skirt_state % n);
  };
  std::size_t k = skirt_pick(shirts.size());
  for (std::size_t tries = 0;
       tries < shirts.size() && ((shirts[k] - o.shirt).norm() < 0.25 || (shirts[k] - o.trousers).norm() < 0.25);
       ++tries) {
    k = (k + 1) % shirts.size();
  }
  o.skirt = shirts[k];
  o.skirt2 = shirts[(k + 1 + skirt_pick(shirts.size() - 1)) % shirts.size()];
  return o;
}

// Periodic soft square wave in [0, 1].
double bands(double x, double period) {
  const double f = x / period - std::floor(x / period);
  return smoothstep(0.42, 0.5, f) - smoothstep(0.92, 1.0, f);
}

// (su, sv): surface coordinates in metres (around, along).
Rgb shirt(const Outfit& o, double su, double sv) {
  Rgb c = o.shirt;
  const double p = o.pattern_period;
  switch (o.shirt_style) {
    case 0:
      c = o.shirt + (o.shirt2 - o.shirt) * bands(sv, p);
      break;
    case 1: {
      const double a = bands(su, 1.7 * p), b = bands(sv, 1.7 * p);
      c = o.shirt + (o.shirt2 - o.shirt) * (0.45 * a + 0.45 * b);
      break;
    }
    case 2:
      c = o.shirt + (o.shirt2 - o.shirt) * smoothstep(0.15, 0.3, fbm(su, sv, 2.0 * p, o.seed + 11));
      break;
    default: {
      const double gx = su / p - std::floor(su / p) - 0.5, gy = sv / p - std::floor(sv / p) - 0.5;
      c = o.shirt + (o.shirt2 - o.shirt) * (1.0 - smoothstep(0.2, 0.26, std::hypot(gx, gy)));
    }
  }
  return vary(c, 0.22 * fbm(su, sv, 0.02, o.seed + 1) + 0.08 * value_noise(su / 0.004, sv / 0.004, o.seed + 2));
}

Rgb trousers(const Outfit& o, double su, double sv, double seam) {
  const double twill = 0.5 + 0.5 * std::sin(2 * M_PI * (su + sv) / 0.008);
  Rgb c = vary(o.trousers, 0.25 * fbm(su, sv, 0.025, o.seed + 3) + 0.08 * twill +
                               0.08 * value_noise(su / 0.003, sv / 0.003, o.seed + 4));
  return vary(c, 0.3 * (1.0 - smoothstep(0.0, 0.006, std::abs(seam))));
}

Rgb skin(const Outfit& o, double su, double sv) {
  return vary(o.skin, 0.16 * fbm(su, sv, 0.03, o.seed + 5) + 0.06 * value_noise(su / 0.005, sv / 0.005, o.seed + 6));
}

Rgb hair(const Outfit& o, double su, double sv) {
  return vary(o.hair, 0.45 * value_noise(su / 0.004, sv / 0.04, o.seed + 7) + 0.2 * fbm(su, sv, 0.03, o.seed + 8));
}

Rgb shoe(const Outfit& o, double su, double sv) {
  return vary(o.shoes, 0.25 * fbm(su, sv, 0.02, o.seed + 9));
}

// Torso chart at height z and folded angle phi (0 = front centre, pi = back centre).
Rgb paint_torso(const BodyModel& body, const Outfit& o, double z, double phi) {
  const double s = body.scale;
  const double zn = z / s;
  const double su = phi * 0.15 * s, sv = z;
  if (zn < 0.985) return trousers(o, su, sv, (phi - M_PI / 2) * 0.15 * s);
  if (zn < 1.03) {
    if (phi < 0.06 * M_PI && zn > 0.993 && zn < 1.022) return vary(rgb(185, 180, 165), 0.1 * value_noise(su / 0.004, sv / 0.004, o.seed + 12));
    return vary(o.belt, 0.25 * value_noise(su / 0.01, sv / 0.01, o.seed + 13));
  }
  const double collar = 1.455 + 0.03 * phi / M_PI;
  if (zn < collar) {
    if (zn > collar - 0.012) return vary(o.shirt2, 0.15 * fbm(su, sv, 0.01, o.seed + 14));  // collar band
    return shirt(o, su, sv);
  }
  // Neck and head.
  const double hu = phi * 0.09 * s;
  const double hairline = 1.70 - 0.14 * smoothstep(0.3 * M_PI, 0.75 * M_PI, phi);
  if (zn > hairline) return hair(o, hu, sv);
  const double eye_phi = 0.1 * M_PI, eye_z = 1.655;
  const double ex = (phi - eye_phi) / (0.035 * M_PI), ez = (zn - eye_z) / 0.008;
  if (ex * ex + ez * ez < 1) {
    const double ix = (phi - eye_phi) / (0.015 * M_PI), iz = (zn - eye_z) / 0.0075;
    if (ix * ix + iz * iz < 1) return o.iris * 0.6;
    return rgb(235, 232, 225);
  }
  if (zn > 1.671 && zn < 1.679 && phi > 0.055 * M_PI && phi < 0.16 * M_PI) return o.hair;  // brows
  if (zn > 1.588 && zn < 1.596 && phi < 0.075 * M_PI) return vary(o.lips, 0.05 * value_noise(hu / 0.004, sv / 0.004, o.seed + 15));
  return skin(o, hu, sv);
}

Rgb paint_arm(const BodyModel& body, const Outfit& o, double t, double phi, double z) {
  const double tn = t / body.scale;
  if (tn < 0) return paint_torso(body, o, z, M_PI / 2);
  const double su = phi * 0.04 * body.scale, sv = -t;
  if (tn < 0.145) return shirt(o, su, sv);
  if (tn < 0.16) return vary(o.shirt2, 0.15 * fbm(su, sv, 0.01, o.seed + 16));  // sleeve hem
  return skin(o, su, sv);
}

Rgb paint_leg(const BodyModel& body, const Outfit& o, double z, double phi) {
  const double zn = z / body.scale;
  if (zn > 0.97) return paint_torso(body, o, z, M_PI / 2);
  const double su = phi * 0.07 * body.scale, sv = z;
  if (zn > 0.125) return trousers(o, su, sv, (phi - M_PI / 2) * 0.07 * body.scale);
  if (zn > 0.112) return vary(o.trousers * 0.8, 0.2 * fbm(su, sv, 0.01, o.seed + 17));  // hem
  return shoe(o, su, sv);
}

// Foot chart: t along the foot from heel (0) to toe (1), phi from the top of the foot.
Rgb paint_foot(const BodyModel& body, const Outfit& o, double t, double phi) {
  const double su = phi * 0.04 * body.scale, sv = t * 0.3 * body.scale;
  if (phi > 0.72 * M_PI) return vary(o.sole, 0.12 * fbm(su, sv, 0.01, o.seed + 18));
  if (phi > 0.66 * M_PI) return vary(o.sole * 0.85, 0.1 * fbm(su, sv, 0.01, o.seed + 19));
  if (phi < 0.12 * M_PI && t > 0.42 && t < 0.72) {
    const double lace = bands(t, 0.06);
    return vary(o.sole * (0.5 + 0.4 * lace) + o.shoes * (0.5 - 0.4 * lace), 0.05);
  }
  return shoe(o, su, sv);
}

// The skirt at folded angle phi and `down` the cloth (0 waist, 1 hem): a print of its second
// colour, a waistband and a band at the hem, fine noise for stereo.
Rgb paint_skirt(const Outfit& o, const SkirtChart& chart, double phi, double down) {
  const double radius = chart.waist_radius + down * chart.length * std::sin(chart.flare);
  const double su = phi * radius, sv = down * chart.length;
  if (down < 0.05) return vary(o.skirt2 * 0.7, 0.2 * value_noise(su / 0.006, sv / 0.006, o.seed + 20));
  if (down > 0.95) return vary(o.skirt2, 0.15 * fbm(su, sv, 0.01, o.seed + 21));
  const Rgb c = o.skirt + (o.skirt2 - o.skirt) * smoothstep(0.1, 0.25, fbm(su, sv, 0.06, o.seed + 22));
  return vary(c, 0.2 * fbm(su, sv, 0.02, o.seed + 23) + 0.08 * value_noise(su / 0.004, sv / 0.004, o.seed + 24));
}

// The atlas at texture coordinates (u, v).
Rgb paint_texel(const BodyModel& body, const Outfit& o, double u, double v,
                const std::optional<SkirtChart>& skirt) {
  if (skirt && u >= 0.5 && u < 0.75 && v >= kSkirtPaintV0) {
    const double phi = std::clamp((u - kSkirtU0) / kSkirtDu, 0.0, 1.0) * M_PI;
    return paint_skirt(o, *skirt, phi, std::clamp((kSkirtV0 + kSkirtDv - v) / kSkirtDv, 0.0, 1.0));
  }
  if (u < 0.5) {
    const double phi = std::clamp((u - kTorsoU0) / kTorsoDu, 0.0, 1.0) * M_PI;
    if (v < kFootTorsoSplitV) {
      const double t = std::clamp((v - kFootV0) / kFootDv, 0.0, 1.0);
      return paint_foot(body, o, t, std::clamp((u - kFootU0) / kFootDu, 0.0, 1.0) * M_PI);
    }
    return paint_torso(body, o, z_of_v(body, v), phi);
  }
  if (u < 0.75) {
    return paint_leg(body, o, z_of_v(body, v), std::clamp((u - kLegU0) / kLegDu, 0.0, 1.0) * M_PI);
  }
  const double shoulder_v = v_of_z(body, body.arms[0].start.z());
  const double t = (shoulder_v - v) / kRowSpan * top(body);
  return paint_arm(body, o, t, std::clamp((u - kArmU0) / kArmDu, 0.0, 1.0) * M_PI, z_of_v(body, v));
}

}  // namespace

Vec2f chart_uv(const BodyModel& body, const ChartRef& ref, const Vector3d& p) {
  const std::size_t side = static_cast<std::size_t>(ref.side);
  switch (ref.chart) {
    case Chart::kTorso: {
      const double phi = std::abs(std::atan2(p.y(), p.x()));
      return {static_cast<float>(kTorsoU0 + kTorsoDu * phi / M_PI), static_cast<float>(v_of_z(body, p.z()))};
    }
    case Chart::kLeg: {
      const LimbAxis& leg = body.legs[side];
      const Vector3d axis = (leg.end - leg.start).normalized();
      const double phi = folded_angle(p - leg.start, axis, Vector3d::UnitX());
      return {static_cast<float>(kLegU0 + kLegDu * phi / M_PI), static_cast<float>(v_of_z(body, p.z()))};
    }
    case Chart::kArm: {
      const LimbAxis& arm = body.arms[side];
      const Vector3d axis = (arm.end - arm.start).normalized();
      const double phi = folded_angle(p - arm.start, axis, Vector3d::UnitX());
      const double t = (p - arm.start).dot(axis);
      return {static_cast<float>(kArmU0 + kArmDu * phi / M_PI),
              static_cast<float>(v_of_z(body, arm.start.z()) - kRowSpan * t / top(body))};
    }
    case Chart::kFoot: {
      const LimbAxis& foot = body.feet[side];
      const Vector3d axis = (foot.end - foot.start).normalized();
      const double phi = folded_angle(p - foot.start, axis, Vector3d::UnitZ());
      const double t = std::clamp((p - foot.start).dot(axis) / (foot.end - foot.start).norm(), 0.0, 1.0);
      return {static_cast<float>(kFootU0 + kFootDu * phi / M_PI), static_cast<float>(kFootV0 + kFootDv * t)};
    }
  }
  return Vec2f::Zero();
}

Vec2f skirt_uv(double phi, double down) {
  return {static_cast<float>(kSkirtU0 + kSkirtDu * std::clamp(phi / M_PI, 0.0, 1.0)),
          static_cast<float>(kSkirtV0 + kSkirtDv * (1 - std::clamp(down, 0.0, 1.0)))};
}

cv::Mat paint_clothing(const BodyModel& body, int size, std::uint64_t seed,
                       const std::optional<Eigen::Vector3d>& key, const std::optional<SkirtChart>& skirt) {
  const Outfit outfit = choose_outfit(seed, key);
  return paint_image(size, [&](double u, double v) { return paint_texel(body, outfit, u, v, skirt); });
}

}  // namespace fourd::synth::detail
