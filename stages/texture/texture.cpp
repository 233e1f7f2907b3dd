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
#include "pipeline/core/staged_folder.h"
#include "pipeline/core/subject.h"
#include "pipeline/exchange/aligned_input.h"
#include "pipeline/exchange/texture_image.h"

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

// The atlas built for the template, and the texels it maps onto the surface (logged).
struct TemplateAtlas {
  Atlas atlas;
  TexelMap texels;
};

TemplateAtlas build_template_atlas(const Mesh& templ, const AtlasOptions& options) {
  log::Timer atlas_timer;
  TemplateAtlas a{build_atlas(templ, options), {}};
  const Atlas& atlas = a.atlas;
  a.texels = map_texels(atlas, templ.triangles);
  const TexelMap& texels = a.texels;
  if (texels.overlapping > 0) {  // a fold of near-degenerate triangles; reported in atlas.json
    log::warn("atlas: {} texel centres lie strictly inside two triangles", texels.overlapping);
  }
  log::info("atlas: {} charts ({} splits), L2 stretch {:.3f} (worst chart {:.3f}), {} flipped, "
            "{:.1f} % of {}x{} texels on the surface, {:.0f} texels/m ({:.1f} s)",
            atlas.charts.size(), atlas.splits, atlas.stretch, atlas.max_stretch,
            atlas.flipped_faces, 100.0 * texels.size() / (double(atlas.resolution) * atlas.resolution),
            atlas.resolution, atlas.resolution, atlas.texels_per_metre, atlas_timer.seconds());
  return a;
}

// What the frames add up to for report.json and the log.
struct Totals {
  json skipped = json::array();
  double seconds = 0, unseen_sum = 0, unseen_max = 0, seam_before = 0, seam_after = 0;
  int frames_done = 0;
};

// Every frame of every take baked into the staged folder, and what it adds to the report.
class FrameBaker {
 public:
  FrameBaker(const Session& session, const std::vector<Camera>& cameras, const TemplateAtlas& a,
             const Mesh& templ, const TextureOptions& options, const std::string& extension,
             const fs::path& staged)
      : session_(session),
        cameras_(cameras),
        a_(a),
        templ_(templ),
        options_(options),
        extension_(extension),
        staged_(staged) {}

  // The take's frames; returns their records.
  json bake_take(const AlignedInput& input, const std::string& take);
  const Totals& totals() const { return totals_; }

 private:
  std::vector<View> frame_views(const std::string& take, int f, json& frame_skipped);
  json bake_frame(const std::string& take, int f, const Eigen::Matrix3Xd& frame);

  const Session& session_;
  const std::vector<Camera>& cameras_;
  const TemplateAtlas& a_;
  const Mesh& templ_;
  const TextureOptions& options_;
  const std::string& extension_;
  const fs::path staged_;
  Totals totals_;
};

json FrameBaker::bake_take(const AlignedInput& input, const std::string& take) {
  const std::vector<Eigen::Matrix3Xd> frames = load_take(input, take);
  log::Progress progress(fmt::format("texture {}", take), frames.size());
  json take_report = json::array();
  for (int f = 0; f < static_cast<int>(frames.size()); ++f) {
    take_report.push_back(bake_frame(take, f, frames[f]));
    progress.step();
  }
  return take_report;
}

// The frame's camera images; a missing or broken one is skipped (and listed) this frame.
std::vector<View> FrameBaker::frame_views(const std::string& take, int f, json& frame_skipped) {
  std::vector<cv::Mat> images(cameras_.size());
  std::vector<std::string> problems(cameras_.size());
  tbb::parallel_for(std::size_t{0}, cameras_.size(), [&](std::size_t c) {
    try {
      images[c] = read_capture_image(session_, cameras_[c], take, f);
    } catch (const Error& e) {  // a missing or broken image: skip that camera this frame
      problems[c] = e.what();
    }
  });
  std::vector<View> views;
  for (std::size_t c = 0; c < cameras_.size(); ++c) {
    if (!problems[c].empty()) {
      log::warn("take {} frame {}: camera {} skipped: {}", take, frame_name(f),
                cameras_[c].name, problems[c]);
      totals_.skipped.push_back({{"take", take}, {"frame", f}, {"camera", cameras_[c].name},
                                 {"reason", problems[c]}});
      frame_skipped.push_back(cameras_[c].name);
      continue;
    }
    views.push_back({&cameras_[c], images[c]});
  }
  return views;
}

// One frame baked and written (texture and unseen mask); returns its record.
json FrameBaker::bake_frame(const std::string& take, int f, const Eigen::Matrix3Xd& frame) {
  log::Timer timer;
  json frame_skipped = json::array();
  const std::vector<View> views = frame_views(take, f, frame_skipped);
  std::vector<Vec3f> positions(frame.cols());
  for (Eigen::Index v = 0; v < frame.cols(); ++v) positions[v] = frame.col(v).cast<float>();
  BakedTexture baked;
  try {
    baked = bake_texture(a_.atlas, a_.texels, positions, templ_.triangles, views, options_.bake);
  } catch (const InputError& e) {
    throw InputError(fmt::format("take {} frame {}: {}", take, frame_name(f), e.what()));
  }
  write_texture(staged_ / take / (frame_name(f) + extension_),
                texture_for_output(baked.color, options_.format == "exr"));
  write_texture(staged_ / take / "unseen" / (frame_name(f) + ".png"), baked.unseen);
  const double frame_seconds = timer.seconds();
  const double unseen = baked.texels ? double(baked.unseen_texels) / baked.texels : 0.0;
  json used = json::object();
  for (std::size_t v = 0; v < views.size(); ++v) used[views[v].camera->name] = baked.texels_per_view[v];
  log::debug("take {} frame {}: {} cameras, {:.2f} % unseen, seams {:.2f} -> {:.2f}, {:.2f} s",
             take, frame_name(f), views.size(), 100 * unseen, baked.seam_rms_before,
             baked.seam_rms_after, frame_seconds);
  totals_.seconds += frame_seconds;
  totals_.unseen_sum += unseen;
  totals_.unseen_max = std::max(totals_.unseen_max, unseen);
  totals_.seam_before += baked.seam_rms_before;
  totals_.seam_after += baked.seam_rms_after;
  ++totals_.frames_done;
  return {{"frame", f},
          {"unseen_texels", baked.unseen_texels},
          {"unseen_fraction", unseen},
          {"texels_per_camera", used},
          {"skipped_cameras", frame_skipped},
          {"seam_rms_before", baked.seam_rms_before},
          {"seam_rms_after", baked.seam_rms_after},
          {"seconds", frame_seconds}};
}

// The atlas as the template with its texture coordinates, its summary and its picture.
void write_atlas_files(const fs::path& dir, const Mesh& templ, const TemplateAtlas& a,
                       const AtlasOptions& options, const std::string& texture) {
  Mesh atlas_mesh = with_atlas_uvs(templ, a.atlas);
  atlas_mesh.texture = texture;  // for MeshLab
  write_ply(dir / "atlas.ply", atlas_mesh);
  write_file_atomic(dir / "atlas.json", atlas_summary(a.atlas, a.texels, options).dump(1));
  write_texture(dir / "atlas.png", atlas_picture(a.atlas, a.texels));
}

// report.json's figures over the frames: their means, the worst, the skipped images.
void add_totals(json& report, const Totals& t) {
  const double n = std::max(t.frames_done, 1);
  report["frames"] = t.frames_done;
  report["seconds_per_frame"] = t.seconds / n;
  report["unseen_fraction_mean"] = t.unseen_sum / n;
  report["unseen_fraction_max"] = t.unseen_max;
  report["seam_rms_before"] = t.seam_before / n;
  report["seam_rms_after"] = t.seam_after / n;
  report["skipped_cameras"] = t.skipped;
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
  const AlignedInput input = open_aligned_input(in);
  // Lengths scale to reconstruct's subject, or to the template's size when align/ was imported.
  const Subject subject =
      stage_subject(session, in, [&] { return measure_subject({input.template_mesh}, in.string()); });
  TextureOptions options;
  subject_stage_options(session, "texture", subject, options);
  const std::string extension = texture_extension(options.format, "stages.texture.format");
  const Mesh& templ = input.template_mesh;
  const std::vector<Camera> cameras = read_colmap_model(session.calibration_dir());
  const std::vector<std::string> takes = aligned_takes(in);
  const TemplateAtlas a = build_template_atlas(templ, options.atlas);

  StagedFolder staged(out);
  write_atlas_files(staged.path(), templ, a, options.atlas,
                    takes.front() + "/" + frame_name(0) + extension);
  json report;
  std::error_code ec;
  report["input"] = fs::relative(in, session.root(), ec).generic_string();
  report["extension"] = extension;
  report["resolution"] = a.atlas.resolution;
  FrameBaker baker(session, cameras, a, templ, options, extension, staged.path());
  for (const std::string& take : takes) report["takes"][take] = baker.bake_take(input, take);
  const Totals& t = baker.totals();
  add_totals(report, t);
  write_file_atomic(staged.path() / "report.json", report.dump(1));
  YAML::Emitter emitter;
  emitter << to_yaml(options);
  write_file_atomic(staged.path() / "options.yaml", std::string(emitter.c_str()) + "\n");
  staged.commit();
  const double n = std::max(t.frames_done, 1);
  log::info("{} frames textured: {:.2f} s per frame, unseen texels {:.2f} % (worst frame "
            "{:.2f} %), seams {:.2f} -> {:.2f} levels, {} camera images skipped; wrote {}",
            t.frames_done, t.seconds / n, 100 * t.unseen_sum / n, 100 * t.unseen_max, t.seam_before / n,
            t.seam_after / n, t.skipped.size(), out.string());
}

}  // namespace fourd::texture
