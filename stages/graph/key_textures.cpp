#include "stages/graph/key_textures.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <nlohmann/json.hpp>
#include <opencv2/imgproc.hpp>

#include "pipeline/core/error.h"
#include "pipeline/core/files.h"
#include "pipeline/core/log.h"
#include "pipeline/core/mesh_io.h"
#include "pipeline/core/session.h"
#include "pipeline/exchange/texture_image.h"

namespace fourd::graph {

namespace fs = std::filesystem;

namespace {

// The take's continuous frame position at every sample of its class (timewarp/<class>.json).
struct TakeFrames {
  int frames = 0;
  std::vector<double> sample_frames;
};

TakeFrames take_frames(const nlohmann::json& summary, const fs::path& file,
                       const std::string& take, int samples) {
  if (summary.contains("takes") && summary["takes"].is_array()) {
    for (const auto& t : summary["takes"]) {
      if (!t.is_object() || t.value("take", "") != take) continue;
      TakeFrames out;
      try {
        out.frames = t.at("frames").get<int>();
        out.sample_frames = t.at("sample_frames").get<std::vector<double>>();
      } catch (const nlohmann::json::exception& e) {
        throw InputError(fmt::format("{}: take '{}': {}", file.string(), take, e.what()));
      }
      if (static_cast<int>(out.sample_frames.size()) != samples || out.frames < 1) {
        throw InputError(fmt::format("{}: take '{}' has {} samples, its motion space {} (rerun "
                                     "the stages from timewarp)",
                                     file.string(), take, out.sample_frames.size(), samples));
      }
      return out;
    }
  }
  throw InputError(fmt::format("{}: no take '{}' (rerun the stages from timewarp)", file.string(),
                               take));
}

fs::path texture_file(const fs::path& dir, const std::string& take, int frame) {
  for (const char* ext : {".png", ".exr"}) {
    fs::path p = dir / take / (frame_name(frame) + ext);
    std::error_code ec;
    if (fs::is_regular_file(p, ec)) return p;
  }
  throw InputError(fmt::format("{}: no texture of take '{}' frame {} (.png or .exr; rerun the "
                               "texture stage)",
                               (dir / take).string(), take, frame_name(frame)));
}

}  // namespace

bool has_textures(const fs::path& texture_dir) {
  std::error_code ec;
  return fs::is_regular_file(texture_dir / "atlas.ply", ec);
}

AssetTextures build_key_textures(const MotionGraph& graph, const fs::path& texture_dir,
                                 const fs::path& timewarp_dir, const KeyTextureOptions& options) {
  AssetTextures out;
  if (options.keys == 0 || graph.spaces.empty()) return out;
  if (options.keys < 2) throw ConfigError("textures.keys: at least 2 key phases (or 0: none)");
  const fs::path atlas_file = texture_dir / "atlas.ply";
  const Mesh atlas = read_ply(atlas_file);
  const std::vector<Tri>& triangles = graph.spaces.front().motion.triangles;
  if (atlas.triangles != triangles) {
    throw InputError(fmt::format("{}: its {} triangles are not the template's {} of the motion "
                                 "spaces (rerun the texture stage)",
                                 atlas_file.string(), atlas.triangles.size(), triangles.size()));
  }
  const bool per_corner = !atlas.uv_triangles.empty();
  if (!per_corner && atlas.uvs.size() != atlas.positions.size()) {
    throw InputError(fmt::format("{}: no texture coordinates", atlas_file.string()));
  }
  out.corner_uvs.reserve(3 * triangles.size());
  for (std::size_t f = 0; f < triangles.size(); ++f) {
    const Tri& t = per_corner ? atlas.uv_triangles[f] : atlas.triangles[f];
    for (int k = 0; k < 3; ++k) out.corner_uvs.push_back(atlas.uvs[t[k]]);
  }
  out.jpeg_quality = options.jpeg_quality;

  for (const GraphSpace& space : graph.spaces) {
    const fs::path summary_file = timewarp_dir / (space.name() + ".json");
    const nlohmann::json summary = [&] {
      try {
        return nlohmann::json::parse(read_file(summary_file));
      } catch (const nlohmann::json::exception& e) {
        throw InputError(fmt::format("{}: {}", summary_file.string(), e.what()));
      }
    }();
    SpaceTextures st;
    st.keys = options.keys;
    st.first = static_cast<int>(out.images.size());
    const int samples = space.num_samples();
    for (const std::string& take : space.motion.takes) {
      const TakeFrames tf = take_frames(summary, summary_file, take, samples);
      for (int k = 0; k < options.keys; ++k) {
        const double t = space.cyclic() ? static_cast<double>(k) / options.keys
                                        : static_cast<double>(k) / (options.keys - 1);
        const double pos = t * (samples - 1);
        const int i = std::min(static_cast<int>(pos), std::max(samples - 2, 0));
        const double a = samples > 1 ? pos - i : 0.0;
        const double frame_pos = samples > 1 ? (1 - a) * tf.sample_frames[i] + a * tf.sample_frames[i + 1]
                                             : tf.sample_frames[0];
        const int frame = std::clamp(static_cast<int>(std::lround(frame_pos)), 0, tf.frames - 1);
        const fs::path file = texture_file(texture_dir, take, frame);
        const cv::Mat baked = read_texture(file);  // float BGR in [0, 1]
        cv::Mat image;
        baked.convertTo(image, CV_8UC3, 255.0);
        if (options.size > 0 && (image.cols != options.size || image.rows != options.size)) {
          cv::Mat resized;
          cv::resize(image, resized, cv::Size(options.size, options.size), 0, 0, cv::INTER_AREA);
          image = resized;
        }
        if (out.images.empty()) {
          out.width = image.cols;
          out.height = image.rows;
        } else if (image.cols != out.width || image.rows != out.height) {
          throw InputError(fmt::format("{}: {} x {} texels, the first key texture has {} x {}",
                                       file.string(), image.cols, image.rows, out.width,
                                       out.height));
        }
        out.images.push_back(image.isContinuous() ? image : image.clone());
      }
    }
    out.spaces.push_back(st);
    log::info("key textures of '{}': {} takes x {} phases", space.name(),
              space.motion.takes.size(), options.keys);
  }
  std::vector<int> inputs;
  for (const GraphSpace& s : graph.spaces) inputs.push_back(s.num_inputs());
  out.check(inputs, triangles.size());
  return out;
}

}  // namespace fourd::graph
