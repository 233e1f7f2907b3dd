#include "runtime/player/render.h"

#include <fmt/format.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <charconv>
#include <cmath>
#include <nlohmann/json.hpp>
#include <numbers>
#include <opencv2/imgproc.hpp>

#include "pipeline/core/colmap_model.h"
#include "pipeline/core/error.h"
#include "pipeline/core/files.h"
#include "pipeline/core/image_io.h"
#include "pipeline/core/log.h"
#include "pipeline/core/process.h"
#include "pipeline/render/textured_render.h"

namespace fourd {

namespace fs = std::filesystem;

namespace {

constexpr double kDeg = std::numbers::pi / 180;

// studio:N -> N; -1 for follow. Throws UsageError otherwise.
int studio_index(const std::string& camera) {
  if (camera == "follow") return -1;
  const std::string prefix = "studio:";
  int n = -1;
  if (camera.rfind(prefix, 0) == 0) {
    const char* begin = camera.data() + prefix.size();
    const char* end = camera.data() + camera.size();
    const auto [ptr, ec] = std::from_chars(begin, end, n);
    if (ec != std::errc() || ptr != end || begin == end) n = -1;
  }
  if (n < 0) {
    throw UsageError(
        fmt::format("--camera '{}': expected follow or studio:N (N a camera index from 0)", camera));
  }
  return n;
}

Intrinsics pinhole(int width, int height, double horizontal_fov_deg) {
  Intrinsics in;
  in.width = width;
  in.height = height;
  in.fx = in.fy = 0.5 * width / std::tan(0.5 * horizontal_fov_deg * kDeg);
  in.cx = 0.5 * width;
  in.cy = 0.5 * height;
  return in;
}

// The ground (z = 0, 0.5 m checkers, the character's shadow) and the sky behind it, under the
// pixels the character does not cover.
void draw_background(const Camera& camera, const MeshRenderer& character, const Shading& light,
                     RenderedView* view) {
  const Intrinsics& in = camera.intrinsics;
  const Eigen::Vector3f sky_top(0.93f, 0.80f, 0.62f), sky_horizon(0.95f, 0.92f, 0.88f);  // BGR
  tbb::parallel_for(0, in.height, [&](int r) {
    cv::Vec3f* row = view->image.ptr<cv::Vec3f>(r);
    const std::uint8_t* mask = view->mask.ptr<std::uint8_t>(r);
    for (int c = 0; c < in.width; ++c) {
      if (mask[c]) continue;
      const Ray ray = camera.unproject({c + 0.5, r + 0.5});
      const Eigen::Vector3d& o = ray.origin;
      const Eigen::Vector3d& d = ray.direction;
      Eigen::Vector3f color;
      if (d.z() < -1e-6 && o.z() > 0) {
        const double t = -o.z() / d.z();
        const Eigen::Vector3d p = o + t * d;
        const bool dark = (static_cast<long>(std::floor(p.x() / 0.5)) +
                           static_cast<long>(std::floor(p.y() / 0.5))) % 2 != 0;
        color = dark ? Eigen::Vector3f(0.50f, 0.52f, 0.52f) : Eigen::Vector3f(0.66f, 0.68f, 0.68f);
        const Eigen::Vector3f origin = p.cast<float>() + Eigen::Vector3f(0, 0, 1e-3f);
        if (character.occluded(origin, light.light, 0.f, 100.f)) color *= 0.55f;
        // Far ground fades into the horizon's haze.
        const float haze = static_cast<float>(1 - std::exp(-t / 40.0));
        color = (1 - haze) * color + haze * sky_horizon;
      } else {
        const float up = static_cast<float>(std::clamp(d.z(), 0.0, 1.0));
        color = (1 - up) * sky_horizon + up * sky_top;
      }
      row[c] = cv::Vec3f(color.x(), color.y(), color.z());
    }
  });
}

}  // namespace

void RenderOptions::check() const {
  if (dir.empty()) throw UsageError("--render: an output folder is needed");
  const int studio = studio_index(camera);
  if (studio >= 0 && calibration.empty()) {
    throw UsageError(fmt::format("--camera {}: --calibration must name the session's "
                                 "calibration/ folder",
                                 camera));
  }
  if (width < 0 || height < 0 || (width == 0) != (height == 0) || width > 16384 ||
      height > 16384) {
    throw UsageError(fmt::format("--image-size {}x{}: both sides from 1 to 16384", width, height));
  }
  if (!(distance > 0)) throw UsageError(fmt::format("--follow-distance {}: must be > 0", distance));
  if (!(field_of_view > 1 && field_of_view < 179)) {
    throw UsageError(fmt::format("field of view {} deg: must lie in (1, 179)", field_of_view));
  }
  if (every < 1) throw UsageError(fmt::format("--render-every {}: must be >= 1", every));
}

struct FrameRenderer::Impl {
  const MotionGraph& graph;
  RenderOptions options;
  int studio = -1;
  Camera camera;
  double look_height = 0.85;  // [m] follow camera's look-at point above the root
  Shading shading;
  std::unique_ptr<MeshRenderer> renderer;
  cv::Mat texture;  // the frame's blended texture (allocated once)
  std::vector<Vec3f> positions;
  std::vector<RenderedFrameStats> stats;
  cv::Mat image8;

  Impl(const MotionGraph& g, const RenderOptions& o) : graph(g), options(o) {}
};

FrameRenderer::FrameRenderer(const MotionGraph& graph, const RenderOptions& options)
    : impl_(std::make_unique<Impl>(graph, options)) {
  Impl& s = *impl_;
  options.check();
  if (graph.spaces.empty()) throw InputError("render: the asset has no motion spaces");
  s.studio = studio_index(options.camera);
  if (s.studio >= 0) {
    const std::vector<Camera> cameras = read_colmap_model(options.calibration);
    if (s.studio >= static_cast<int>(cameras.size())) {
      throw InputError(fmt::format("{}: --camera {}: the calibration has {} cameras (0 to {})",
                                   options.calibration.string(), options.camera, cameras.size(),
                                   cameras.size() - 1));
    }
    s.camera = cameras[s.studio];
    if (options.width > 0) {  // the same view at another resolution
      Intrinsics& in = s.camera.intrinsics;
      const double sx = static_cast<double>(options.width) / in.width;
      const double sy = static_cast<double>(options.height) / in.height;
      in.fx *= sx;
      in.cx *= sx;
      in.fy *= sy;
      in.cy *= sy;
      in.width = options.width;
      in.height = options.height;
    }
  } else {
    s.camera.name = "follow";
    s.camera.intrinsics = pinhole(options.width > 0 ? options.width : 640,
                                  options.height > 0 ? options.height : 480,
                                  options.field_of_view);
  }
  const MotionSpace& first = graph.spaces.front().motion;
  if (first.character_height > 0) s.look_height = 0.5 * first.character_height;

  Mesh mesh;
  mesh.triangles = first.triangles;
  const float* rest = first.blend.frame(0, 0);  // planes x | y | z
  const std::size_t stride = first.blend.plane_stride;
  for (int v = 0; v < first.blend.num_vertices; ++v) {
    mesh.positions.emplace_back(rest[v], rest[stride + v], rest[2 * stride + v]);
  }
  const AssetTextures& textures = graph.textures;
  if (!textures.empty()) {
    mesh.uvs = textures.corner_uvs;
    mesh.uv_triangles.resize(mesh.triangles.size());
    for (std::size_t f = 0; f < mesh.triangles.size(); ++f) {
      const int k = static_cast<int>(3 * f);
      mesh.uv_triangles[f] = Tri(k, k + 1, k + 2);
    }
    s.texture = textures.images.front().clone();
    s.renderer = std::make_unique<MeshRenderer>(mesh, s.texture);
  } else {
    s.renderer = std::make_unique<MeshRenderer>(mesh, s.shading);
  }
  ensure_directory(options.dir);
  log::info("rendering to {}: camera {}, {} x {}, {}", options.dir.string(), options.camera,
            s.camera.intrinsics.width, s.camera.intrinsics.height,
            textures.empty() ? "shaded (the asset has no textures)" : "textured");
}

FrameRenderer::~FrameRenderer() = default;

bool FrameRenderer::textured() const { return impl_->renderer->textured(); }
const Camera& FrameRenderer::camera() const { return impl_->camera; }
const std::vector<RenderedFrameStats>& FrameRenderer::stats() const { return impl_->stats; }

void FrameRenderer::on_frame(int index, double time, const Character& character) {
  Impl& s = *impl_;
  if (index % s.options.every != 0) return;
  const CharacterFrame& frame = character.frame();
  character_world_positions(frame, &s.positions);
  s.renderer->set_positions(s.positions);
  if (s.renderer->textured()) {
    blend_texture_image(s.graph.textures, frame.textures, &s.texture);
    s.renderer->set_texture(s.texture);
  }
  if (s.studio < 0) {
    const RenderOptions& o = s.options;
    const double az = (o.azimuth + o.orbit * time) * kDeg, el = o.elevation * kDeg;
    const Eigen::Vector3d target(frame.root.x, frame.root.y, s.look_height);
    const Eigen::Vector3d eye =
        target + o.distance * Eigen::Vector3d(std::cos(el) * std::cos(az),
                                              std::cos(el) * std::sin(az), std::sin(el));
    s.camera.camera_from_world = look_at(eye, target, Eigen::Vector3d::UnitZ());
  }
  RenderedView view = s.renderer->render(s.camera);
  RenderedFrameStats st;
  st.frame = index;
  const cv::Moments m = cv::moments(view.mask, true);
  const double pixels = static_cast<double>(view.mask.total());
  st.foreground = m.m00 / pixels;
  if (m.m00 > 0) {
    st.centroid_x = (m.m10 / m.m00 + 0.5) / view.mask.cols;
    st.centroid_y = (m.m01 / m.m00 + 0.5) / view.mask.rows;
  }
  s.stats.push_back(st);
  draw_background(s.camera, *s.renderer, s.shading, &view);
  view.image.convertTo(s.image8, CV_8UC3, 255.0);
  write_image_atomic(s.options.dir / fmt::format("frame_{:05d}.png", index), s.image8,
                     {cv::IMWRITE_PNG_COMPRESSION, 3});
}

void FrameRenderer::finish(double fps) {
  Impl& s = *impl_;
  const RenderOptions& o = s.options;
  nlohmann::json j;
  j["camera"] = o.camera;
  j["width"] = s.camera.intrinsics.width;
  j["height"] = s.camera.intrinsics.height;
  j["textured"] = textured();
  j["frames"] = s.stats.size();
  double lo = 1, hi = 0, worst_offset = 0;
  for (const RenderedFrameStats& st : s.stats) {
    lo = std::min(lo, st.foreground);
    hi = std::max(hi, st.foreground);
    if (st.foreground > 0) {
      worst_offset = std::max({worst_offset, std::abs(st.centroid_x - 0.5),
                               std::abs(st.centroid_y - 0.5)});
    }
    j["per_frame"].push_back({{"frame", st.frame},
                              {"foreground", st.foreground},
                              {"centroid", {st.centroid_x, st.centroid_y}}});
  }
  j["foreground_min"] = s.stats.empty() ? 0.0 : lo;
  j["foreground_max"] = hi;
  j["max_centroid_offset"] = worst_offset;  // from the image centre, in image sizes
  if (!o.mp4.empty()) {
    const std::string ffmpeg = find_executable("ffmpeg");
    if (ffmpeg.empty()) {
      log::warn("--mp4 {}: ffmpeg is not on PATH (Debian package ffmpeg); the frames are in {}",
                o.mp4.string(), o.dir.string());
      j["mp4"] = {{"file", o.mp4.string()}, {"written", false}, {"reason", "ffmpeg not on PATH"}};
    } else if (s.stats.empty()) {
      log::warn("--mp4 {}: no frames were rendered", o.mp4.string());
      j["mp4"] = {{"file", o.mp4.string()}, {"written", false}, {"reason", "no frames"}};
    } else {
      if (o.mp4.has_parent_path()) ensure_directory(o.mp4.parent_path());
      const fs::path temp = temp_path_for(o.mp4);
      const fs::path log_file = o.dir / "ffmpeg.log";
      const int code = run_process(
          {ffmpeg, "-y", "-loglevel", "error", "-framerate", fmt::format("{}", fps / o.every),
           "-pattern_type", "glob", "-i", (o.dir / "frame_*.png").string(), "-c:v", "libx264",
           "-pix_fmt", "yuv420p", "-vf", "pad=ceil(iw/2)*2:ceil(ih/2)*2", "-f", "mp4",
           temp.string()},
          log_file);
      if (code != 0) {
        std::error_code ec;
        fs::remove(temp, ec);
        throw IoError(fmt::format("--mp4 {}: ffmpeg failed (exit {}), see {}", o.mp4.string(),
                                  code, log_file.string()));
      }
      commit_temp_file(temp, o.mp4);
      log::info("wrote {} ({} frames at {:.3g} fps)", o.mp4.string(), s.stats.size(),
                fps / o.every);
      j["mp4"] = {{"file", o.mp4.string()}, {"written", true}};
    }
  }
  write_file_atomic(o.dir / "render.json", j.dump(1) + "\n");
}

}  // namespace fourd
