#include "runtime/mesh_sequence.h"

#include <fmt/format.h>

#include <cmath>
#include <nlohmann/json.hpp>

#include "pipeline/core/error.h"
#include "pipeline/core/files.h"
#include "pipeline/core/mesh_io.h"
#include "pipeline/core/staged_folder.h"

namespace fourd {

void SequenceOptions::check() const {
  if (format != "ply" && format != "obj")
    throw UsageError(fmt::format("--sequence-format {}: expected ply or obj", format));
  texture.check();
}

namespace {

nlohmann::json box_json(const Vec3f& lo, const Vec3f& hi) {
  return {{"min", {lo.x(), lo.y(), lo.z()}}, {"max", {hi.x(), hi.y(), hi.z()}}};
}

// A root-frame point or direction in the world of the root pose.
Vec3f to_world(const Vec3f& p, const RootTransform& root, bool point) {
  const double c = std::cos(root.heading), s = std::sin(root.heading);
  return Vec3f(static_cast<float>((point ? root.x : 0) + c * p.x() - s * p.y()),
               static_cast<float>((point ? root.y : 0) + s * p.x() + c * p.y()), p.z());
}

}  // namespace

SequenceReport write_mesh_sequence(const std::filesystem::path& dir, const Asset& asset,
                                   const MeshClip& clip, double fps,
                                   const SequenceOptions& options) {
  options.check();
  const Mesh base = asset_template(asset);
  const AssetTextures& textures = asset.graph.textures;
  const bool textured = !textures.empty();
  const std::size_t vertices = base.num_vertices();
  if (clip.num_frames() == 0 || clip.roots.size() != clip.times.size() ||
      clip.normals.size() != clip.times.size() ||
      (textured && clip.textures.size() != clip.times.size()))
    throw InputError(fmt::format("{}: clip '{}' has {} frames, {} roots, {} textures",
                                 dir.string(), clip.name, clip.num_frames(), clip.roots.size(),
                                 clip.textures.size()));
  StagedFolder staged(dir);
  Mesh mesh = base;
  cv::Mat image;
  nlohmann::json frames = nlohmann::json::array();
  Vec3f all_lo = Vec3f::Constant(std::numeric_limits<float>::infinity()), all_hi = -all_lo;
  for (int f = 0; f < clip.num_frames(); ++f) {
    if (clip.positions[f].size() != vertices || clip.normals[f].size() != vertices)
      throw InputError(fmt::format("{}: clip '{}' frame {} has {} vertices, the asset {}",
                                   dir.string(), clip.name, f, clip.positions[f].size(), vertices));
    const RootTransform& root = clip.roots[f];
    for (std::size_t v = 0; v < vertices; ++v) {
      mesh.positions[v] = to_world(clip.positions[f][v], root, true);
      const Vec3f n = to_world(clip.normals[f][v], root, false);
      mesh.normals[v] = n.norm() > 1e-12f ? Vec3f(n.normalized()) : Vec3f(0, 0, 1);
    }
    const std::string stem = fmt::format("frame_{:05d}", f);
    nlohmann::json frame;
    frame["index"] = f;
    frame["time"] = clip.times[f];
    frame["mesh"] = stem + "." + options.format;
    if (textured) {
      blend_texture_image(textures, clip.textures[f], &image);
      mesh.texture = stem + options.texture.extension();
      write_file_atomic(staged.path() / mesh.texture, [&] {
        const std::vector<unsigned char> bytes = encode_texture(image, options.texture);
        return std::string(bytes.begin(), bytes.end());
      }());
      frame["texture"] = mesh.texture;
    }
    write_mesh(staged.path() / frame["mesh"].get<std::string>(), mesh);
    Vec3f lo, hi;
    bounding_box(mesh, &lo, &hi);
    all_lo = all_lo.cwiseMin(lo);
    all_hi = all_hi.cwiseMax(hi);
    frame["bounding_box"] = box_json(lo, hi);
    frame["root"] = {{"x", root.x}, {"y", root.y}, {"heading_rad", root.heading}};
    frames.push_back(std::move(frame));
  }
  nlohmann::json manifest;
  manifest["format"] = "fourd mesh sequence";
  manifest["version"] = 1;
  manifest["clip"] = clip.name;
  manifest["fps"] = fps;
  manifest["frame_count"] = clip.num_frames();
  manifest["duration_s"] = clip.times.back() - clip.times.front();
  manifest["vertices"] = vertices;
  manifest["triangles"] = base.num_triangles();
  manifest["mesh_format"] = options.format;
  manifest["texture_format"] = textured ? nlohmann::json(options.texture.format) : nlohmann::json();
  manifest["axes"] = "metres; z up, the character faces +x at heading 0";
  manifest["bounding_box"] = box_json(all_lo, all_hi);
  manifest["frames"] = std::move(frames);
  write_file_atomic(staged.path() / "sequence.json", manifest.dump(1));
  SequenceReport report;
  for (const auto& entry : std::filesystem::directory_iterator(staged.path()))
    report.bytes += entry.file_size();
  staged.commit();
  report.frames = clip.num_frames();
  report.fps = fps;
  return report;
}

}  // namespace fourd
