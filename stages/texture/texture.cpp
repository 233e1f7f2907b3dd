#include "stages/texture/texture.h"

#include <fmt/format.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <nlohmann/json.hpp>

#include "pipeline/core/capture.h"
#include "pipeline/core/colmap_model.h"
#include "pipeline/core/error.h"
#include "pipeline/core/files.h"
#include "pipeline/core/log.h"
#include "pipeline/core/mesh_io.h"
#include "pipeline/core/subject.h"
#include "stages/texture/texture_io.h"
#include "pipeline/core/staged_folder.h"
#include "stages/timewarp/timewarp.h"

namespace fourd::texture {
namespace {

namespace fs = std::filesystem;
using json = nlohmann::json;

// Takes of the aligned input: its sub-folders, without align's sequential baseline.
std::vector<std::string> aligned_takes(const fs::path& dir) {
  std::vector<std::string> takes;
  for (const auto& entry : fs::directory_iterator(dir)) {
    const std::string name = entry.path().filename().string();
    if (!entry.is_directory() || name.front() == '.' || name == "sequential") continue;
    takes.push_back(name);
  }
  std::sort(takes.begin(), takes.end());
  if (takes.empty()) throw InputError(fmt::format("{}: no aligned takes", dir.string()));
  return takes;
}

// Every chart in its own colour, gutters black: what the atlas looks like.
cv::Mat atlas_picture(const Atlas& atlas, const TexelMap& texels) {
  cv::Mat picture = cv::Mat::zeros(atlas.resolution, atlas.resolution, CV_8UC3);
  for (std::size_t s = 0; s < texels.size(); ++s) {
    const int chart = atlas.face_chart[texels.face[s]];
    const std::uint64_t h = hash_bytes(std::string_view(reinterpret_cast<const char*>(&chart), sizeof chart));
    const int y = texels.texel[s] / atlas.resolution, x = texels.texel[s] % atlas.resolution;
    picture.at<cv::Vec3b>(y, x) = cv::Vec3b(64 + (h & 0x7f), 64 + ((h >> 8) & 0x7f), 64 + ((h >> 16) & 0x7f));
  }
  return picture;
}

json atlas_summary(const Atlas& atlas, const TexelMap& texels, const AtlasOptions& options) {
  return {{"resolution", atlas.resolution},
          {"gutter_texels", atlas.gutter},
          {"method", options.method},
          {"charts", atlas.charts.size()},
          {"splits", atlas.splits},
          {"stretch_l2", atlas.stretch},
          {"max_chart_stretch_l2", atlas.max_stretch},
          {"flipped_faces", atlas.flipped_faces},
          {"overlapping_texels", texels.overlapping},
          {"texels_per_metre", atlas.texels_per_metre},
          {"surface_texels", texels.size()},
          {"coverage", static_cast<double>(texels.size()) /
                           (static_cast<double>(atlas.resolution) * atlas.resolution)}};
}

}  // namespace

void TextureOptions::check() const {
  atlas.check();
  texture_extension(format, "format");
}

void run_texture(const Session& session, const StageArgs& args) {
  const fs::path in = stage_input_dir(session, args, "align");
  const fs::path out = stage_output_dir(session, args, "texture");
  log::info("reading aligned meshes from {}", in.string());
  const timewarp::AlignedInput input = timewarp::open_aligned_input(in);
  // Lengths scale to reconstruct's subject, or to the template's size when align/ was imported.
  const Subject subject =
      stage_subject(session, in, [&] { return measure_subject({input.template_mesh}, in.string()); });
  TextureOptions options;
  subject_stage_options(session, "texture", subject, options);
  const std::string extension = texture_extension(options.format, "stages.texture.format");
  const Mesh& templ = input.template_mesh;
  const std::vector<Camera> cameras = read_colmap_model(session.calibration_dir());
  const std::vector<std::string> takes = aligned_takes(in);

  log::Timer atlas_timer;
  const Atlas atlas = build_atlas(templ, options.atlas);
  const TexelMap texels = map_texels(atlas, templ.triangles);
  if (texels.overlapping > 0) {  // a fold of near-degenerate triangles; reported in atlas.json
    log::warn("atlas: {} texel centres lie strictly inside two triangles", texels.overlapping);
  }
  log::info("atlas: {} charts ({} splits), L2 stretch {:.3f} (worst chart {:.3f}), {} flipped, "
            "{:.1f} % of {}x{} texels on the surface, {:.0f} texels/m ({:.1f} s)",
            atlas.charts.size(), atlas.splits, atlas.stretch, atlas.max_stretch,
            atlas.flipped_faces, 100.0 * texels.size() / (double(atlas.resolution) * atlas.resolution),
            atlas.resolution, atlas.resolution, atlas.texels_per_metre, atlas_timer.seconds());

  StagedFolder staged(out);
  Mesh atlas_mesh = with_atlas_uvs(templ, atlas);
  atlas_mesh.texture = takes.front() + "/" + frame_name(0) + extension;  // for MeshLab
  write_ply(staged.path() / "atlas.ply", atlas_mesh);
  write_file_atomic(staged.path() / "atlas.json",
                    atlas_summary(atlas, texels, options.atlas).dump(1));
  write_texture(staged.path() / "atlas.png", atlas_picture(atlas, texels));

  json report;
  std::error_code ec;
  report["input"] = fs::relative(in, session.root(), ec).generic_string();
  report["extension"] = extension;
  report["resolution"] = atlas.resolution;
  json skipped = json::array();
  double seconds = 0, unseen_sum = 0, unseen_max = 0, seam_before = 0, seam_after = 0;
  int frames_done = 0;
  for (const std::string& take : takes) {
    const std::vector<Eigen::Matrix3Xd> frames = timewarp::load_take(input, take);
    log::Progress progress(fmt::format("texture {}", take), frames.size());
    json take_report = json::array();
    for (int f = 0; f < static_cast<int>(frames.size()); ++f) {
      log::Timer timer;
      std::vector<cv::Mat> images(cameras.size());
      std::vector<std::string> problems(cameras.size());
      tbb::parallel_for(std::size_t{0}, cameras.size(), [&](std::size_t c) {
        try {
          images[c] = read_capture_image(session, cameras[c], take, f);
        } catch (const Error& e) {  // a missing or broken image: skip that camera this frame
          problems[c] = e.what();
        }
      });
      std::vector<View> views;
      json frame_skipped = json::array();
      for (std::size_t c = 0; c < cameras.size(); ++c) {
        if (!problems[c].empty()) {
          log::warn("take {} frame {}: camera {} skipped: {}", take, frame_name(f),
                    cameras[c].name, problems[c]);
          skipped.push_back({{"take", take}, {"frame", f}, {"camera", cameras[c].name},
                             {"reason", problems[c]}});
          frame_skipped.push_back(cameras[c].name);
          continue;
        }
        views.push_back({&cameras[c], images[c]});
      }
      std::vector<Vec3f> positions(frames[f].cols());
      for (Eigen::Index v = 0; v < frames[f].cols(); ++v) positions[v] = frames[f].col(v).cast<float>();
      BakedTexture baked;
      try {
        baked = bake_texture(atlas, texels, positions, templ.triangles, views, options.bake);
      } catch (const InputError& e) {
        throw InputError(fmt::format("take {} frame {}: {}", take, frame_name(f), e.what()));
      }
      write_texture(staged.path() / take / (frame_name(f) + extension),
                    texture_for_output(baked.color, options.format == "exr"));
      write_texture(staged.path() / take / "unseen" / (frame_name(f) + ".png"), baked.unseen);
      const double frame_seconds = timer.seconds();
      const double unseen = baked.texels ? double(baked.unseen_texels) / baked.texels : 0.0;
      json used = json::object();
      for (std::size_t v = 0; v < views.size(); ++v) used[views[v].camera->name] = baked.texels_per_view[v];
      take_report.push_back({{"frame", f},
                             {"unseen_texels", baked.unseen_texels},
                             {"unseen_fraction", unseen},
                             {"texels_per_camera", used},
                             {"skipped_cameras", frame_skipped},
                             {"seam_rms_before", baked.seam_rms_before},
                             {"seam_rms_after", baked.seam_rms_after},
                             {"seconds", frame_seconds}});
      log::debug("take {} frame {}: {} cameras, {:.2f} % unseen, seams {:.2f} -> {:.2f}, {:.2f} s",
                 take, frame_name(f), views.size(), 100 * unseen, baked.seam_rms_before,
                 baked.seam_rms_after, frame_seconds);
      seconds += frame_seconds;
      unseen_sum += unseen;
      unseen_max = std::max(unseen_max, unseen);
      seam_before += baked.seam_rms_before;
      seam_after += baked.seam_rms_after;
      ++frames_done;
      progress.step();
    }
    report["takes"][take] = take_report;
  }
  const double n = std::max(frames_done, 1);
  report["frames"] = frames_done;
  report["seconds_per_frame"] = seconds / n;
  report["unseen_fraction_mean"] = unseen_sum / n;
  report["unseen_fraction_max"] = unseen_max;
  report["seam_rms_before"] = seam_before / n;
  report["seam_rms_after"] = seam_after / n;
  report["skipped_cameras"] = skipped;
  write_file_atomic(staged.path() / "report.json", report.dump(1));
  YAML::Emitter emitter;
  emitter << to_yaml(options);
  write_file_atomic(staged.path() / "options.yaml", std::string(emitter.c_str()) + "\n");
  staged.commit();
  log::info("{} frames textured: {:.2f} s per frame, unseen texels {:.2f} % (worst frame "
            "{:.2f} %), seams {:.2f} -> {:.2f} levels, {} camera images skipped; wrote {}",
            frames_done, seconds / n, 100 * unseen_sum / n, 100 * unseen_max, seam_before / n,
            seam_after / n, skipped.size(), out.string());
}

}  // namespace fourd::texture
