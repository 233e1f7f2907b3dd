#pragma once
// Test-only: an orthographic z-buffer rasteriser to look at synthetic meshes (front and side
// views, textured and Lambert-shaded). Used when FOURD_SYNTH_DEBUG_DIR names a folder.
#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <limits>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <string>
#include <vector>

#include "pipeline/core/mesh.h"

namespace fourd::synth::debug_view {

// Where to write debug images, or empty when they are not wanted.
inline std::string debug_dir() {
  const char* dir = std::getenv("FOURD_SYNTH_DEBUG_DIR");
  return dir ? std::string(dir) : std::string();
}

// View direction: the camera looks along -`toward` (e.g. toward = +x: looking at the front of
// a performer facing +x). `right` is the image's right direction; up is +z.
inline cv::Mat render_orthographic(const Mesh& mesh, const cv::Mat& texture, const Eigen::Vector3f& toward,
                                   const Eigen::Vector3f& right, const Eigen::Vector3f& centre,
                                   float pixels_per_metre, int width, int height) {
  cv::Mat image(height, width, CV_8UC3, cv::Scalar(60, 60, 60));
  std::vector<float> depth(static_cast<std::size_t>(width * height), std::numeric_limits<float>::lowest());
  const Eigen::Vector3f up(0, 0, 1);
  const Eigen::Vector3f light = Eigen::Vector3f(0.5f, 0.3f, 0.8f).normalized();
  auto project = [&](const Vec3f& p) {
    const Eigen::Vector3f q = p - centre;
    return Eigen::Vector3f(width / 2.0f + q.dot(right) * pixels_per_metre,
                           height / 2.0f - q.dot(up) * pixels_per_metre, q.dot(toward));
  };
  for (const Tri& t : mesh.triangles) {
    const Vec3f& a = mesh.positions[t[0]];
    const Vec3f& b = mesh.positions[t[1]];
    const Vec3f& c = mesh.positions[t[2]];
    const Eigen::Vector3f n = (b - a).cross(c - a).normalized();
    if (n.dot(toward) <= 0) continue;  // back face
    const float shade = 0.35f + 0.65f * std::max(0.0f, n.dot(light));
    const Eigen::Vector3f pa = project(a), pb = project(b), pc = project(c);
    const int x0 = std::max(0, static_cast<int>(std::floor(std::min({pa.x(), pb.x(), pc.x()}))));
    const int x1 = std::min(width - 1, static_cast<int>(std::ceil(std::max({pa.x(), pb.x(), pc.x()}))));
    const int y0 = std::max(0, static_cast<int>(std::floor(std::min({pa.y(), pb.y(), pc.y()}))));
    const int y1 = std::min(height - 1, static_cast<int>(std::ceil(std::max({pa.y(), pb.y(), pc.y()}))));
    const float area = (pb.x() - pa.x()) * (pc.y() - pa.y()) - (pb.y() - pa.y()) * (pc.x() - pa.x());
    if (std::abs(area) < 1e-12f) continue;
    for (int y = y0; y <= y1; ++y) {
      for (int x = x0; x <= x1; ++x) {
        const float px = x + 0.5f, py = y + 0.5f;
        const float w0 = ((pb.x() - px) * (pc.y() - py) - (pb.y() - py) * (pc.x() - px)) / area;
        const float w1 = ((pc.x() - px) * (pa.y() - py) - (pc.y() - py) * (pa.x() - px)) / area;
        const float w2 = 1 - w0 - w1;
        if (w0 < 0 || w1 < 0 || w2 < 0) continue;
        const float z = w0 * pa.z() + w1 * pb.z() + w2 * pc.z();
        float& zb = depth[static_cast<std::size_t>(y * width + x)];
        if (z <= zb) continue;
        zb = z;
        cv::Vec3f colour(200, 200, 200);
        if (!texture.empty() && mesh.uvs.size() == mesh.positions.size()) {
          const Vec2f uv = w0 * mesh.uvs[t[0]] + w1 * mesh.uvs[t[1]] + w2 * mesh.uvs[t[2]];
          const int tx = std::clamp(static_cast<int>(uv.x() * texture.cols), 0, texture.cols - 1);
          const int ty = std::clamp(static_cast<int>((1 - uv.y()) * texture.rows), 0, texture.rows - 1);
          const cv::Vec3b texel = texture.at<cv::Vec3b>(ty, tx);
          colour = cv::Vec3f(texel[0], texel[1], texel[2]);
        }
        image.at<cv::Vec3b>(y, x) = cv::Vec3b(cv::saturate_cast<uchar>(colour[0] * shade),
                                              cv::saturate_cast<uchar>(colour[1] * shade),
                                              cv::saturate_cast<uchar>(colour[2] * shade));
      }
    }
  }
  return image;
}

// Front, side and back views side by side, framed on the mesh's bounding box.
inline cv::Mat render_views(const Mesh& mesh, const cv::Mat& texture, int size = 400) {
  Vec3f lo, hi;
  bounding_box(mesh, &lo, &hi);
  const Vec3f centre = 0.5f * (lo + hi);
  const float extent = std::max({hi.x() - lo.x(), hi.y() - lo.y(), hi.z() - lo.z()});
  const float ppm = 0.9f * size / extent;
  cv::Mat front = render_orthographic(mesh, texture, {1, 0, 0}, {0, -1, 0}, centre, ppm, size, size);
  cv::Mat side = render_orthographic(mesh, texture, {0, -1, 0}, {1, 0, 0}, centre, ppm, size, size);
  cv::Mat back = render_orthographic(mesh, texture, {-1, 0, 0}, {0, 1, 0}, centre, ppm, size, size);
  cv::Mat out;
  cv::hconcat(std::vector<cv::Mat>{front, side, back}, out);
  return out;
}

inline void write_debug_image(const std::string& name, const cv::Mat& image) {
  const std::string dir = debug_dir();
  if (!dir.empty()) cv::imwrite(dir + "/" + name, image);
}

}  // namespace fourd::synth::debug_view
