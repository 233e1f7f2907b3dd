#include "pipeline/exchange/atlas.h"

#include <algorithm>
#include <cmath>
#include <limits>

namespace fourd {
namespace {

using Eigen::Vector2d;

double distance_to_segment(const Vector2d& p, const Vector2d& a, const Vector2d& b, double* t) {
  const Vector2d ab = b - a;
  const double len2 = ab.squaredNorm();
  *t = len2 > 0 ? std::clamp((p - a).dot(ab) / len2, 0.0, 1.0) : 0.0;
  return (p - (a + *t * ab)).norm();
}

}  // namespace

TexelMap map_texels(const Atlas& atlas, const std::vector<Tri>& triangles, double reach) {
  const int res = atlas.resolution;
  TexelMap map;
  map.resolution = res;
  const std::size_t n = static_cast<std::size_t>(res) * res;
  std::vector<float> best(n, std::numeric_limits<float>::infinity());
  std::vector<int> best_face(n, -1);
  std::vector<Eigen::Vector3f> best_bary(n);
  std::vector<int> strict_face(n, -1);
  constexpr double kStrict = 1e-4;
  for (int f = 0; f < static_cast<int>(triangles.size()); ++f) {
    const Tri& ut = atlas.uv_triangles[f];
    const Vector2d a = atlas.texel(atlas.uvs[ut[0]]), b = atlas.texel(atlas.uvs[ut[1]]),
                   c = atlas.texel(atlas.uvs[ut[2]]);
    const double det = (b - a).x() * (c - a).y() - (b - a).y() * (c - a).x();
    if (!(std::abs(det) > 1e-12)) continue;
    const Vector2d lo = a.cwiseMin(b).cwiseMin(c), hi = a.cwiseMax(b).cwiseMax(c);
    const int x0 = std::max(0, static_cast<int>(std::floor(lo.x() - reach - 0.5)));
    const int y0 = std::max(0, static_cast<int>(std::floor(lo.y() - reach - 0.5)));
    const int x1 = std::min(res - 1, static_cast<int>(std::ceil(hi.x() + reach - 0.5)));
    const int y1 = std::min(res - 1, static_cast<int>(std::ceil(hi.y() + reach - 0.5)));
    for (int y = y0; y <= y1; ++y) {
      for (int x = x0; x <= x1; ++x) {
        const Vector2d p(x + 0.5, y + 0.5);
        const double l1 = ((p - a).x() * (c - a).y() - (p - a).y() * (c - a).x()) / det;
        const double l2 = ((b - a).x() * (p - a).y() - (b - a).y() * (p - a).x()) / det;
        const double l0 = 1 - l1 - l2;
        const std::size_t i = static_cast<std::size_t>(y) * res + x;
        float dist = 0;
        Eigen::Vector3f bary(static_cast<float>(l0), static_cast<float>(l1), static_cast<float>(l2));
        if (l0 < 0 || l1 < 0 || l2 < 0) {
          // Outside: the nearest point of the triangle, if within reach.
          double tab, tbc, tca;
          const double dab = distance_to_segment(p, a, b, &tab);
          const double dbc = distance_to_segment(p, b, c, &tbc);
          const double dca = distance_to_segment(p, c, a, &tca);
          const double d = std::min({dab, dbc, dca});
          if (d > reach) continue;
          dist = static_cast<float>(d);
          if (d == dab) {
            bary = Eigen::Vector3f(static_cast<float>(1 - tab), static_cast<float>(tab), 0);
          } else if (d == dbc) {
            bary = Eigen::Vector3f(0, static_cast<float>(1 - tbc), static_cast<float>(tbc));
          } else {
            bary = Eigen::Vector3f(static_cast<float>(tca), 0, static_cast<float>(1 - tca));
          }
        } else if (l0 > kStrict && l1 > kStrict && l2 > kStrict) {
          if (strict_face[i] >= 0 && strict_face[i] != f) ++map.overlapping;
          strict_face[i] = f;
        }
        if (dist < best[i]) {
          best[i] = dist;
          best_face[i] = f;
          best_bary[i] = bary;
        }
      }
    }
  }
  map.sample_of.assign(n, -1);
  for (std::size_t i = 0; i < n; ++i) {
    if (best_face[i] < 0) continue;
    map.sample_of[i] = static_cast<int>(map.texel.size());
    map.texel.push_back(static_cast<int>(i));
    map.face.push_back(best_face[i]);
    map.bary.push_back(best_bary[i]);
  }
  return map;
}

}  // namespace fourd
