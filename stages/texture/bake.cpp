#include "stages/texture/bake.h"

#include <fmt/format.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <deque>
#include <opencv2/imgproc.hpp>

#include "pipeline/core/error.h"
#include "pipeline/render/triangle_scene.h"

namespace fourd::texture {
namespace {

using Eigen::Vector2d;
using Eigen::Vector3d;
using Eigen::Vector3f;

// Weight of a camera's pixels by their distance inside the mesh's outline in its image: 0 at
// the outline (pixels there mix in the backdrop), 1 from `ramp` pixels inside. CV_32F.
cv::Mat outline_weight(const Camera& camera, const std::vector<Vec3f>& positions,
                       const std::vector<Tri>& triangles, double ramp) {
  const Intrinsics& in = camera.intrinsics;
  cv::Mat mask = cv::Mat::zeros(in.height, in.width, CV_8U);
  constexpr int kShift = 4;  // sub-pixel bits of the polygon corners
  std::vector<cv::Point> projected(positions.size());
  std::vector<char> valid(positions.size(), 0);
  for (std::size_t i = 0; i < positions.size(); ++i) {
    Eigen::Vector2d px;
    if (!camera.project(positions[i].cast<double>(), &px)) continue;
    // OpenCV puts pixel centres at integers, the calibration at +0.5.
    projected[i] = cv::Point(static_cast<int>(std::lround((px.x() - 0.5) * (1 << kShift))),
                             static_cast<int>(std::lround((px.y() - 0.5) * (1 << kShift))));
    valid[i] = 1;
  }
  for (const Tri& t : triangles) {
    if (!valid[t[0]] || !valid[t[1]] || !valid[t[2]]) continue;
    const cv::Point corners[3] = {projected[t[0]], projected[t[1]], projected[t[2]]};
    cv::fillConvexPoly(mask, corners, 3, cv::Scalar(255), cv::LINE_8, kShift);
  }
  cv::Mat distance;
  cv::distanceTransform(mask, distance, cv::DIST_L2, 3);
  if (ramp <= 0) {
    cv::threshold(distance, distance, 0, 1.0, cv::THRESH_BINARY);
    return distance;
  }
  // The first pixel inside is at distance 1.
  distance = (distance - 0.5) / ramp;
  cv::threshold(distance, distance, 1.0, 1.0, cv::THRESH_TRUNC);
  cv::threshold(distance, distance, 0.0, 0.0, cv::THRESH_TOZERO);
  return distance;
}

// Colours of the vertices from the seen texels around them; vertices no seen texel touches
// take the mean of their neighbours, layer by layer from the seen ones. False when no texel
// was seen at all.
bool vertex_colors(const TexelMap& texels, const std::vector<Tri>& triangles, std::size_t num_vertices,
                   const std::vector<Vector3f>& color, const std::vector<char>& seen,
                   std::vector<Vector3f>* out) {
  std::vector<Vector3f> sum(num_vertices, Vector3f::Zero());
  std::vector<float> weight(num_vertices, 0.0f);
  for (std::size_t s = 0; s < texels.size(); ++s) {
    if (!seen[s]) continue;
    const Tri& t = triangles[texels.face[s]];
    for (int k = 0; k < 3; ++k) {
      sum[t[k]] += texels.bary[s][k] * color[s];
      weight[t[k]] += texels.bary[s][k];
    }
  }
  std::vector<std::vector<int>> neighbours(num_vertices);
  for (const Tri& t : triangles) {
    for (int k = 0; k < 3; ++k) {
      neighbours[t[k]].push_back(t[(k + 1) % 3]);
      neighbours[t[k]].push_back(t[(k + 2) % 3]);
    }
  }
  out->assign(num_vertices, Vector3f::Zero());
  std::vector<char> known(num_vertices, 0);
  std::deque<int> frontier;
  for (std::size_t v = 0; v < num_vertices; ++v) {
    if (weight[v] > 1e-6f) {
      (*out)[v] = sum[v] / weight[v];
      known[v] = 1;
      frontier.push_back(static_cast<int>(v));
    }
  }
  if (frontier.empty()) return false;
  // Breadth-first from the known vertices: each new vertex averages its known neighbours.
  while (!frontier.empty()) {
    const int v = frontier.front();
    frontier.pop_front();
    for (int nb : neighbours[v]) {
      if (known[nb]) continue;
      Vector3f c = Vector3f::Zero();
      int n = 0;
      for (int k : neighbours[nb]) {
        if (known[k] == 1) {
          c += (*out)[k];
          ++n;
        }
      }
      (*out)[nb] = c / static_cast<float>(std::max(n, 1));
      known[nb] = 1;
      frontier.push_back(nb);
    }
  }
  return true;
}

// Seam levelling. Along every mesh edge where two charts meet, both sides are looked up at
// matching points; each side is corrected by half the difference, and the correction fades
// linearly into its chart over `width` texels (breadth-first within the chart). Returns the
// RMS difference across seams before and after [0..1 colour units].
std::pair<double, double> level_seams(const Atlas& atlas, const TexelMap& texels,
                                      const std::vector<Tri>& triangles, int width,
                                      cv::Mat& color /* CV_32FC3 */) {
  const int res = atlas.resolution;
  const auto neighbours = face_neighbours(triangles);
  struct SeamPoint {
    Vector2d a, b;  // texel coordinates on either side
    int face_a, face_b;
  };
  std::vector<SeamPoint> points;
  for (int f = 0; f < static_cast<int>(triangles.size()); ++f) {
    for (int k = 0; k < 3; ++k) {
      const int g = neighbours[f][k];
      if (g < f || atlas.face_chart[g] == atlas.face_chart[f]) continue;
      const int va = triangles[f][k], vb = triangles[f][(k + 1) % 3];
      const Vector2d a0 = atlas.texel(atlas.uvs[atlas.uv_triangles[f][k]]);
      const Vector2d a1 = atlas.texel(atlas.uvs[atlas.uv_triangles[f][(k + 1) % 3]]);
      Vector2d b0, b1;
      for (int j = 0; j < 3; ++j) {
        if (triangles[g][j] == va) b0 = atlas.texel(atlas.uvs[atlas.uv_triangles[g][j]]);
        if (triangles[g][j] == vb) b1 = atlas.texel(atlas.uvs[atlas.uv_triangles[g][j]]);
      }
      const int n = std::max(2, static_cast<int>(std::ceil(std::max((a1 - a0).norm(), (b1 - b0).norm()))));
      for (int i = 0; i < n; ++i) {
        const double t = (i + 0.5) / n;
        points.push_back({a0 + t * (a1 - a0), b0 + t * (b1 - b0), f, g});
      }
    }
  }
  if (points.empty()) return {0.0, 0.0};

  auto rms = [&]() {
    double sum = 0;
    for (const SeamPoint& p : points) {
      sum += (sample_bilinear(color, p.a.x(), p.a.y()) - sample_bilinear(color, p.b.x(), p.b.y()))
                 .squaredNorm() / 3.0;
    }
    return std::sqrt(sum / static_cast<double>(points.size()));
  };
  const double before = rms();
  if (width <= 0) return {before, before};

  // Corrections at the texels under each seam point (bilinear footprint, own chart only).
  const std::size_t n = static_cast<std::size_t>(res) * res;
  std::vector<Vector3f> correction(n, Vector3f::Zero());
  std::vector<float> weight(n, 0.0f);
  auto splat = [&](const Vector2d& p, int face, const Vector3f& c) {
    const double x = p.x() - 0.5, y = p.y() - 0.5;
    const int x0 = static_cast<int>(std::floor(x)), y0 = static_cast<int>(std::floor(y));
    const double fx = x - x0, fy = y - y0;
    const int chart = atlas.face_chart[face];
    for (int dy = 0; dy <= 1; ++dy) {
      for (int dx = 0; dx <= 1; ++dx) {
        const int xx = x0 + dx, yy = y0 + dy;
        if (xx < 0 || yy < 0 || xx >= res || yy >= res) continue;
        const std::size_t i = static_cast<std::size_t>(yy) * res + xx;
        const int s = texels.sample_of[i];
        if (s < 0 || atlas.face_chart[texels.face[s]] != chart) continue;
        const float w = static_cast<float>((dx ? fx : 1 - fx) * (dy ? fy : 1 - fy));
        correction[i] += w * c;
        weight[i] += w;
      }
    }
  };
  for (const SeamPoint& p : points) {
    const Vector3f d = sample_bilinear(color, p.a.x(), p.a.y()) - sample_bilinear(color, p.b.x(), p.b.y());
    splat(p.a, p.face_a, -0.5f * d);
    splat(p.b, p.face_b, 0.5f * d);
  }
  // Fade inwards: breadth-first from the corrected texels within their chart.
  std::vector<int> source(n, -1), depth(n, 0);
  std::deque<std::size_t> queue;
  for (std::size_t i = 0; i < n; ++i) {
    if (weight[i] > 1e-4f) {
      correction[i] /= weight[i];
      source[i] = static_cast<int>(i);
      queue.push_back(i);
    }
  }
  while (!queue.empty()) {
    const std::size_t i = queue.front();
    queue.pop_front();
    if (depth[i] >= width) continue;
    const int x = static_cast<int>(i % res), y = static_cast<int>(i / res);
    const int chart = atlas.face_chart[texels.face[texels.sample_of[i]]];
    const int dx[4] = {1, -1, 0, 0}, dy[4] = {0, 0, 1, -1};
    for (int k = 0; k < 4; ++k) {
      const int xx = x + dx[k], yy = y + dy[k];
      if (xx < 0 || yy < 0 || xx >= res || yy >= res) continue;
      const std::size_t j = static_cast<std::size_t>(yy) * res + xx;
      const int s = texels.sample_of[j];
      if (source[j] >= 0 || s < 0 || atlas.face_chart[texels.face[s]] != chart) continue;
      source[j] = source[i];
      depth[j] = depth[i] + 1;
      queue.push_back(j);
    }
  }
  for (std::size_t i = 0; i < n; ++i) {
    if (source[i] < 0) continue;
    const float fade = 1.0f - static_cast<float>(depth[i]) / static_cast<float>(width + 1);
    const Vector3f c = fade * correction[source[i]];
    cv::Vec3f& px = color.at<cv::Vec3f>(static_cast<int>(i / res), static_cast<int>(i % res));
    for (int ch = 0; ch < 3; ++ch) px[ch] = std::clamp(px[ch] + c[ch], 0.0f, 1.0f);
  }
  return {before, rms()};
}

// Dilates the filled texels by `rings` rings (each new texel the mean of its filled
// 8-neighbours), so lookups at chart borders read surface colours rather than gutter.
void dilate(cv::Mat& color, std::vector<char>& filled, int rings) {
  const int res = color.rows;
  for (int ring = 0; ring < rings; ++ring) {
    std::vector<std::pair<std::size_t, cv::Vec3f>> added;
    for (int y = 0; y < res; ++y) {
      for (int x = 0; x < res; ++x) {
        if (filled[static_cast<std::size_t>(y) * res + x]) continue;
        cv::Vec3f sum(0, 0, 0);
        int n = 0;
        for (int yy = std::max(0, y - 1); yy <= std::min(res - 1, y + 1); ++yy) {
          for (int xx = std::max(0, x - 1); xx <= std::min(res - 1, x + 1); ++xx) {
            if (!filled[static_cast<std::size_t>(yy) * res + xx]) continue;
            sum += color.at<cv::Vec3f>(yy, xx);
            ++n;
          }
        }
        if (n) added.push_back({static_cast<std::size_t>(y) * res + x, sum / n});
      }
    }
    for (const auto& [i, c] : added) {
      color.at<cv::Vec3f>(static_cast<int>(i / res), static_cast<int>(i % res)) = c;
      filled[i] = 1;
    }
  }
}

// The texels still empty after dilation take the mean surface colour (keeps mipmaps clean).
void fill_background(cv::Mat& color, const std::vector<char>& surface, const std::vector<char>& filled) {
  const int res = color.rows;
  cv::Vec3d mean(0, 0, 0);
  std::size_t count = 0;
  for (std::size_t i = 0; i < surface.size(); ++i) {
    if (!surface[i]) continue;
    mean += cv::Vec3d(color.at<cv::Vec3f>(static_cast<int>(i / res), static_cast<int>(i % res)));
    ++count;
  }
  if (count) mean /= static_cast<double>(count);
  for (std::size_t i = 0; i < filled.size(); ++i) {
    if (!filled[i]) color.at<cv::Vec3f>(static_cast<int>(i / res), static_cast<int>(i % res)) = cv::Vec3f(mean);
  }
}

}  // namespace

cv::Mat texture_for_output(const cv::Mat& color, bool float_output) {
  if (float_output) return color;
  cv::Mat out;
  color.convertTo(out, CV_8UC3, 255.0);
  return out;
}

BakedTexture bake_texture(const Atlas& atlas, const TexelMap& texels,
                          const std::vector<Vec3f>& positions, const std::vector<Tri>& triangles,
                          const std::vector<View>& views, const BakeOptions& options) {
  const int res = atlas.resolution;
  Mesh posed;
  posed.positions = positions;
  posed.triangles = triangles;
  compute_vertex_normals(posed);
  const TriangleScene scene(positions, triangles);

  struct ViewData {
    Vector3d centre;
    double focal = 0;
    cv::Mat weight;  // outline weight, CV_32F
  };
  std::vector<ViewData> data(views.size());
  tbb::parallel_for(std::size_t{0}, views.size(), [&](std::size_t v) {
    const Camera& camera = *views[v].camera;
    data[v].centre = camera.center();
    data[v].focal = 0.5 * (camera.intrinsics.fx + camera.intrinsics.fy);
    data[v].weight = outline_weight(camera, positions, triangles, options.edge_pixels);
  });

  const std::size_t n = texels.size();
  std::vector<Vector3f> color(n, Vector3f::Zero());
  std::vector<char> seen(n, 0);
  std::vector<std::atomic<int>> per_view(views.size());
  const float offset = static_cast<float>(options.occlusion_offset);
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, n, 1024), [&](const auto& range) {
    std::vector<int> counts(views.size(), 0);
    for (std::size_t s = range.begin(); s < range.end(); ++s) {
      const Tri& t = triangles[texels.face[s]];
      const Vector3f& b = texels.bary[s];
      const Vector3f p = b[0] * positions[t[0]] + b[1] * positions[t[1]] + b[2] * positions[t[2]];
      Vector3f normal = b[0] * posed.normals[t[0]] + b[1] * posed.normals[t[1]] + b[2] * posed.normals[t[2]];
      Vector3f face_normal = (positions[t[1]] - positions[t[0]]).cross(positions[t[2]] - positions[t[0]]);
      if (normal.squaredNorm() == 0 || face_normal.squaredNorm() == 0) continue;
      normal.normalize();
      face_normal.normalize();
      Vector3f sum = Vector3f::Zero();
      float total = 0;
      for (std::size_t v = 0; v < views.size(); ++v) {
        const Vector3f to_camera = data[v].centre.cast<float>() - p;
        const float distance = to_camera.norm();
        const Vector3f dir = to_camera / distance;
        const float cosine = normal.dot(dir);
        if (cosine < options.min_cos || face_normal.dot(dir) <= 0) continue;
        const Camera& camera = *views[v].camera;
        Eigen::Vector2d px;
        if (!camera.project(p.cast<double>(), &px) || !camera.in_image(px)) continue;
        const float edge = data[v].weight.at<float>(static_cast<int>(px.y()), static_cast<int>(px.x()));
        if (edge <= 0) continue;
        if (scene.occluded(p + offset * face_normal, dir, 0.0f, distance - 2 * offset)) continue;
        const float resolution = static_cast<float>(data[v].focal / distance);
        const float w = std::pow(cosine, static_cast<float>(options.angle_power)) * edge *
                        resolution * resolution;
        sum += w * sample_bilinear(views[v].image, px.x(), px.y());
        total += w;
        ++counts[v];
      }
      if (total > 0) {
        color[s] = sum / total;
        seen[s] = 1;
      }
    }
    for (std::size_t v = 0; v < views.size(); ++v) per_view[v] += counts[v];
  });

  BakedTexture out;
  out.texels = static_cast<int>(n);
  for (const auto& c : per_view) out.texels_per_view.push_back(c.load());
  std::vector<Vector3f> vertex_color;
  if (!vertex_colors(texels, triangles, positions.size(), color, seen, &vertex_color)) {
    throw InputError("no camera sees any part of the surface");
  }
  out.unseen = cv::Mat::zeros(res, res, CV_8U);
  out.color = cv::Mat::zeros(res, res, CV_32FC3);
  std::vector<char> filled(static_cast<std::size_t>(res) * res, 0);
  for (std::size_t s = 0; s < n; ++s) {
    const int texel = texels.texel[s];
    const int y = texel / res, x = texel % res;
    if (!seen[s]) {
      const Tri& t = triangles[texels.face[s]];
      const Vector3f& b = texels.bary[s];
      color[s] = b[0] * vertex_color[t[0]] + b[1] * vertex_color[t[1]] + b[2] * vertex_color[t[2]];
      out.unseen.at<std::uint8_t>(y, x) = 255;
      ++out.unseen_texels;
    }
    out.color.at<cv::Vec3f>(y, x) = cv::Vec3f(color[s].x(), color[s].y(), color[s].z());
    filled[texel] = 1;
  }
  // Seam lookups read a texel or two beyond the chart borders: dilate first, and again after
  // levelling so the gutters carry the levelled colours.
  const std::vector<char> surface = filled;
  std::vector<char> ring = filled;
  dilate(out.color, ring, 2);
  const auto [before, after] = level_seams(atlas, texels, triangles, options.seam_width, out.color);
  out.seam_rms_before = 255.0 * before;
  out.seam_rms_after = 255.0 * after;
  dilate(out.color, filled, atlas.gutter);
  fill_background(out.color, surface, filled);
  return out;
}

}  // namespace fourd::texture
