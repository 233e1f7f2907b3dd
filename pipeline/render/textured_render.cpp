#include "pipeline/render/textured_render.h"

#include <fmt/format.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>

#include "pipeline/core/error.h"
#include "pipeline/render/triangle_scene.h"

namespace fourd {

namespace {

void check_texture(const cv::Mat& texture) {
  if (texture.empty() || (texture.type() != CV_8UC3 && texture.type() != CV_32FC3)) {
    throw InputError("render: the texture must be a non-empty 3-channel image");
  }
}

}  // namespace

struct MeshRenderer::Impl {
  std::vector<Vec3f> positions;
  std::vector<Tri> triangles;
  std::vector<std::array<Vec2f, 3>> corner_uv;  // per face; empty: shaded
  cv::Mat texture;
  Shading shading;
  std::unique_ptr<TriangleScene> scene;
};

MeshRenderer::MeshRenderer(const Mesh& mesh, const cv::Mat& texture)
    : impl_(std::make_unique<Impl>()) {
  Impl& s = *impl_;
  const bool per_corner = !mesh.uv_triangles.empty();
  if (!per_corner && mesh.uvs.size() != mesh.positions.size()) {
    throw InputError("render: the mesh has no texture coordinates");
  }
  check_texture(texture);
  s.positions = mesh.positions;
  s.triangles = mesh.triangles;
  s.texture = texture;
  s.corner_uv.resize(mesh.triangles.size());
  for (std::size_t f = 0; f < mesh.triangles.size(); ++f) {
    const Tri& t = per_corner ? mesh.uv_triangles[f] : mesh.triangles[f];
    for (int k = 0; k < 3; ++k) s.corner_uv[f][k] = mesh.uvs[t[k]];
  }
  s.scene = std::make_unique<TriangleScene>(s.positions, s.triangles);
}

MeshRenderer::MeshRenderer(const Mesh& mesh, const Shading& shading)
    : impl_(std::make_unique<Impl>()) {
  Impl& s = *impl_;
  s.positions = mesh.positions;
  s.triangles = mesh.triangles;
  s.shading = shading;
  s.shading.light.normalize();
  s.scene = std::make_unique<TriangleScene>(s.positions, s.triangles);
}

MeshRenderer::~MeshRenderer() = default;

void MeshRenderer::set_positions(const std::vector<Vec3f>& positions) {
  Impl& s = *impl_;
  if (positions.size() != s.positions.size()) {
    throw InputError(fmt::format("render: {} positions for a mesh of {} vertices",
                                 positions.size(), s.positions.size()));
  }
  s.positions = positions;
  s.scene = std::make_unique<TriangleScene>(s.positions, s.triangles);
}

void MeshRenderer::set_texture(const cv::Mat& texture) {
  if (impl_->corner_uv.empty()) throw InputError("render: a shaded renderer takes no texture");
  check_texture(texture);
  impl_->texture = texture;
}

bool MeshRenderer::textured() const { return !impl_->corner_uv.empty(); }

bool MeshRenderer::occluded(const Eigen::Vector3f& origin, const Eigen::Vector3f& direction,
                            float tnear, float tfar) const {
  return impl_->scene->occluded(origin, direction, tnear, tfar);
}

RenderedView MeshRenderer::render(const Camera& camera) const {
  const Impl& s = *impl_;
  const Intrinsics& in = camera.intrinsics;
  RenderedView out;
  out.image = cv::Mat::zeros(in.height, in.width, CV_32FC3);
  out.mask = cv::Mat::zeros(in.height, in.width, CV_8U);
  // Only the pixels around the projected mesh can hit it.
  double x0 = std::numeric_limits<double>::max(), y0 = x0, x1 = -x0, y1 = -x0;
  bool behind = false;
  for (const Vec3f& p : s.positions) {
    Eigen::Vector2d px;
    if (!camera.project(p.cast<double>(), &px)) {
      behind = true;  // part of the mesh behind the camera: its projection is unbounded
      continue;
    }
    x0 = std::min(x0, px.x());
    y0 = std::min(y0, px.y());
    x1 = std::max(x1, px.x());
    y1 = std::max(y1, px.y());
  }
  if (behind) {
    x0 = y0 = 0;
    x1 = in.width;
    y1 = in.height;
  }
  if (x1 < x0) return out;
  const int c0 = std::max(0, static_cast<int>(std::floor(x0)) - 2);
  const int r0 = std::max(0, static_cast<int>(std::floor(y0)) - 2);
  const int c1 = std::min(in.width - 1, static_cast<int>(std::ceil(x1)) + 2);
  const int r1 = std::min(in.height - 1, static_cast<int>(std::ceil(y1)) + 2);
  if (c1 < c0 || r1 < r0) return out;
  const double tw = s.texture.cols, th = s.texture.rows;
  const bool textured = !s.corner_uv.empty();
  tbb::parallel_for(r0, r1 + 1, [&](int r) {
    cv::Vec3f* row = out.image.ptr<cv::Vec3f>(r);
    std::uint8_t* mask = out.mask.ptr<std::uint8_t>(r);
    for (int c = c0; c <= c1; ++c) {
      const Ray ray = camera.unproject({c + 0.5, r + 0.5});
      const SceneHit hit = s.scene->intersect(ray.origin.cast<float>(), ray.direction.cast<float>());
      if (hit.face < 0) continue;
      Eigen::Vector3f color;
      if (textured) {
        const auto& uv = s.corner_uv[hit.face];
        const Vec2f q = hit.bary[0] * uv[0] + hit.bary[1] * uv[1] + hit.bary[2] * uv[2];
        color = sample_bilinear(s.texture, q.x() * tw, (1.0 - q.y()) * th);
      } else {
        const Tri& t = s.triangles[hit.face];
        Eigen::Vector3f n = (s.positions[t[1]] - s.positions[t[0]])
                                .cross(s.positions[t[2]] - s.positions[t[0]])
                                .normalized();
        if (n.dot(ray.direction.cast<float>()) > 0) n = -n;
        const float lambert = std::max(0.f, n.dot(s.shading.light));
        color = s.shading.albedo * (s.shading.ambient + (1 - s.shading.ambient) * lambert);
      }
      row[c] = cv::Vec3f(color.x(), color.y(), color.z());
      mask[c] = 255;
    }
  });
  return out;
}

Eigen::Vector3f sample_bilinear(const cv::Mat& image, double x, double y) {
  const double fx0 = std::clamp(x - 0.5, 0.0, image.cols - 1.0);
  const double fy0 = std::clamp(y - 0.5, 0.0, image.rows - 1.0);
  const int x0 = std::min(static_cast<int>(fx0), image.cols - 1);
  const int y0 = std::min(static_cast<int>(fy0), image.rows - 1);
  const int x1 = std::min(x0 + 1, image.cols - 1), y1 = std::min(y0 + 1, image.rows - 1);
  const float ax = static_cast<float>(fx0 - x0), ay = static_cast<float>(fy0 - y0);
  auto at = [&](int r, int c) -> Eigen::Vector3f {
    if (image.type() == CV_32FC3) {
      const cv::Vec3f& p = image.at<cv::Vec3f>(r, c);
      return {p[0], p[1], p[2]};
    }
    const cv::Vec3b& p = image.at<cv::Vec3b>(r, c);
    return Eigen::Vector3f(p[0], p[1], p[2]) / 255.0f;
  };
  return (1 - ay) * ((1 - ax) * at(y0, x0) + ax * at(y0, x1)) +
         ay * ((1 - ax) * at(y1, x0) + ax * at(y1, x1));
}

double ImageError::psnr_db() const {
  if (values == 0) return 0;
  const double mse = sum_squared / static_cast<double>(values);
  if (mse <= 0) return std::numeric_limits<double>::infinity();
  return 10.0 * std::log10(255.0 * 255.0 / mse);
}

ImageError image_error(const cv::Mat& rendered, const cv::Mat& image, const cv::Mat& mask) {
  if (rendered.size() != image.size() || mask.size() != image.size()) {
    throw InputError(fmt::format("image_error: sizes differ ({}x{}, {}x{}, {}x{})", rendered.cols,
                                 rendered.rows, image.cols, image.rows, mask.cols, mask.rows));
  }
  ImageError e;
  for (int r = 0; r < image.rows; ++r) {
    const cv::Vec3f* a = rendered.ptr<cv::Vec3f>(r);
    const cv::Vec3b* b = image.ptr<cv::Vec3b>(r);
    const std::uint8_t* m = mask.ptr<std::uint8_t>(r);
    for (int c = 0; c < image.cols; ++c) {
      if (!m[c]) continue;
      for (int ch = 0; ch < 3; ++ch) {
        const double d = 255.0 * a[c][ch] - b[c][ch];
        e.sum_squared += d * d;
      }
      e.values += 3;
    }
  }
  return e;
}

}  // namespace fourd
