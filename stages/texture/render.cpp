#include "stages/texture/render.h"

#include <fmt/format.h>
#include <tbb/parallel_for.h>

#include <cmath>
#include <limits>

#include "pipeline/core/error.h"
#include "stages/texture/bake.h"
#include "stages/texture/scene.h"

namespace fourd::texture {

struct TexturedRenderer::Impl {
  std::vector<Vec3f> positions;
  std::vector<Tri> triangles;
  std::vector<std::array<Vec2f, 3>> corner_uv;  // per face
  cv::Mat texture;
  std::unique_ptr<TriangleScene> scene;
};

TexturedRenderer::TexturedRenderer(const Mesh& mesh, const cv::Mat& texture)
    : impl_(std::make_unique<Impl>()) {
  Impl& s = *impl_;
  const bool per_corner = !mesh.uv_triangles.empty();
  if (!per_corner && mesh.uvs.size() != mesh.positions.size()) {
    throw InputError("render: the mesh has no texture coordinates");
  }
  if (texture.empty() || (texture.type() != CV_8UC3 && texture.type() != CV_32FC3)) {
    throw InputError("render: the texture must be a non-empty 3-channel image");
  }
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

TexturedRenderer::~TexturedRenderer() = default;

TexturedView TexturedRenderer::render(const Camera& camera) const {
  const Impl& s = *impl_;
  const Intrinsics& in = camera.intrinsics;
  TexturedView out;
  out.image = cv::Mat::zeros(in.height, in.width, CV_32FC3);
  out.mask = cv::Mat::zeros(in.height, in.width, CV_8U);
  // Only the pixels around the projected mesh can hit it.
  double x0 = std::numeric_limits<double>::max(), y0 = x0, x1 = -x0, y1 = -x0;
  for (const Vec3f& p : s.positions) {
    Eigen::Vector2d px;
    if (!camera.project(p.cast<double>(), &px)) continue;
    x0 = std::min(x0, px.x());
    y0 = std::min(y0, px.y());
    x1 = std::max(x1, px.x());
    y1 = std::max(y1, px.y());
  }
  if (x1 < x0) return out;
  const int c0 = std::max(0, static_cast<int>(std::floor(x0)) - 2);
  const int r0 = std::max(0, static_cast<int>(std::floor(y0)) - 2);
  const int c1 = std::min(in.width - 1, static_cast<int>(std::ceil(x1)) + 2);
  const int r1 = std::min(in.height - 1, static_cast<int>(std::ceil(y1)) + 2);
  if (c1 < c0 || r1 < r0) return out;
  const double tw = s.texture.cols, th = s.texture.rows;
  tbb::parallel_for(r0, r1 + 1, [&](int r) {
    cv::Vec3f* row = out.image.ptr<cv::Vec3f>(r);
    std::uint8_t* mask = out.mask.ptr<std::uint8_t>(r);
    for (int c = c0; c <= c1; ++c) {
      const Ray ray = camera.unproject({c + 0.5, r + 0.5});
      const SceneHit hit = s.scene->intersect(ray.origin.cast<float>(), ray.direction.cast<float>());
      if (hit.face < 0) continue;
      const auto& uv = s.corner_uv[hit.face];
      const Vec2f q = hit.bary[0] * uv[0] + hit.bary[1] * uv[1] + hit.bary[2] * uv[2];
      const Eigen::Vector3f color = sample_bilinear(s.texture, q.x() * tw, (1.0 - q.y()) * th);
      row[c] = cv::Vec3f(color.x(), color.y(), color.z());
      mask[c] = 255;
    }
  });
  return out;
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

}  // namespace fourd::texture
