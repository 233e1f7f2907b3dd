// Validation of the texture stage (texture/ on pipeline meshes, texture_oracle/ on the
// ground-truth meshes): each sampled frame's aligned mesh, textured with its baked texture, is
// rendered into every studio camera and compared with the captured image over the pixels inside
// the ground-truth silhouette (eroded by one pixel: the outline mixes in the backdrop) that the
// render covers. texture.<input>.psnr_db pools the squared error of all those pixels.
#include <fmt/format.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <opencv2/imgproc.hpp>

#include "pipeline/core/capture.h"
#include "pipeline/core/colmap_model.h"
#include "pipeline/core/error.h"
#include "pipeline/core/image_io.h"
#include "pipeline/core/mesh_io.h"
#include "pipeline/exchange/atlas.h"
#include "pipeline/exchange/texture_image.h"
#include "pipeline/render/textured_render.h"
#include "stages/validate/sampling.h"
#include "stages/validate/validate.h"

namespace fourd::validate {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;
using fourd::ImageError;

struct CameraResult {
  ImageError error;
  std::int64_t silhouette = 0;  // pixels inside the eroded ground-truth silhouette
  std::int64_t compared = 0;    // ... that the render covers
  cv::Mat picture;              // captured | rendered | difference (sampled frames only)
};

// Renders one frame into every camera and compares.
std::vector<CameraResult> compare_frame(const Session& session, const Mesh& textured,
                                        const cv::Mat& texture_image,
                                        const std::vector<Camera>& cameras, const std::string& take,
                                        int frame, bool pictures) {
  const MeshRenderer renderer(textured, texture_image);
  std::vector<CameraResult> results(cameras.size());
  tbb::parallel_for(std::size_t{0}, cameras.size(), [&](std::size_t c) {
    const Camera& camera = cameras[c];
    const cv::Mat captured = read_capture_image(session, camera, take, frame);
    const fs::path silhouette_file = session.ground_truth_dir() / "silhouettes" / take /
                                     camera.name / (frame_name(frame) + ".png");
    cv::Mat silhouette = read_image(silhouette_file, cv::IMREAD_GRAYSCALE);
    cv::erode(silhouette > 127, silhouette, cv::Mat());
    const RenderedView view = renderer.render(camera);
    const cv::Mat mask = silhouette & view.mask;
    CameraResult& r = results[c];
    r.error = image_error(view.image, captured, mask);
    r.silhouette = cv::countNonZero(silhouette);
    r.compared = cv::countNonZero(mask);
    if (pictures) {
      cv::Mat rendered, diff;
      view.image.convertTo(rendered, CV_8UC3, 255.0);
      cv::absdiff(rendered, captured, diff);
      diff.setTo(cv::Scalar::all(0), ~mask);
      diff.convertTo(diff, CV_8UC3, 4.0);
      r.picture = captured.clone();
      cv::hconcat(std::vector<cv::Mat>{r.picture, rendered, diff}, r.picture);
    }
  });
  return results;
}

// The texels the bake maps onto the surface (centres inside a chart's triangle), as the
// texture stage finds them.
cv::Mat chart_mask(const Mesh& atlas, int resolution) {
  Atlas charts;
  charts.resolution = resolution;
  charts.uvs = atlas.uvs;
  charts.uv_triangles = atlas.uv_triangles;
  const TexelMap texels = map_texels(charts, atlas.triangles, /*reach=*/0.0);
  cv::Mat mask = cv::Mat::zeros(resolution, resolution, CV_8U);
  for (int t : texels.texel) mask.at<std::uint8_t>(t / resolution, t % resolution) = 255;
  return mask;
}

}  // namespace

double texture_flicker(const fs::path& dir, const std::string& extension,
                       const std::vector<std::pair<std::string, int>>& frames_per_take,
                       const Mesh& atlas) {
  cv::Mat mask;
  double sum = 0;
  int pairs = 0;
  for (const auto& [take, frames] : frames_per_take) {
    cv::Mat previous;
    for (int frame = 0; frame < frames; ++frame) {
      const fs::path file = dir / take / (frame_name(frame) + extension);
      cv::Mat image = read_texture(file);
      if (mask.empty()) mask = chart_mask(atlas, image.cols);
      if (image.size() != mask.size()) {
        throw InputError(fmt::format("{}: {}x{} texels, the take's first texture has {}x{}",
                                     file.string(), image.cols, image.rows, mask.cols, mask.rows));
      }
      if (!previous.empty()) {
        cv::Mat change;
        cv::absdiff(image, previous, change);
        const cv::Scalar m = cv::mean(change, mask);
        sum += 255.0 * (m[0] + m[1] + m[2]) / 3.0;
        ++pairs;
      }
      previous = std::move(image);
    }
  }
  return pairs ? sum / pairs : 0.0;
}

namespace {

// The errors of the compared pixels, summed over frames (or takes).
struct Tally {
  ImageError error;
  std::int64_t silhouette = 0, compared = 0;
};

// One texture run folder's validation: every take's sampled frames rendered and compared, the
// pictures of one frame, the metrics and the table rows.
class TextureRun {
 public:
  TextureRun(const ValidationContext& ctx, const RunFolder& run, const std::vector<Camera>& cameras,
             StageReport& report, std::string& table)
      : ctx_(ctx),
        run_(run),
        cameras_(cameras),
        report_(report),
        table_(table),
        stage_report_(read_json(run.dir / "report.json")),
        input_(ctx.session.root() / stage_report_.at("input").get<std::string>()),
        extension_(stage_report_.at("extension").get<std::string>()),
        textured_(read_ply(run.dir / "atlas.ply")) {
    if (textured_.uv_triangles.empty()) {
      throw InputError(fmt::format("{}: no per-corner texture coordinates", (run.dir / "atlas.ply").string()));
    }
    for (const auto& [take, frames] : stage_report_.at("takes").items()) takes_.push_back(take);
  }

  void validate();

 private:
  int frame_count(const std::string& take) const {
    return static_cast<int>(stage_report_.at("takes").at(take).size());
  }
  Tally compare_take(std::size_t k, std::size_t* frames_compared);
  void add_pictures(const std::vector<cv::Mat>& rows, const std::string& take, int frame,
                    const cv::Mat& image);
  void add_metrics(const Tally& total);

  const ValidationContext& ctx_;
  const RunFolder& run_;
  const std::vector<Camera>& cameras_;
  StageReport& report_;
  std::string& table_;
  const json stage_report_;
  const fs::path input_;
  const std::string extension_;
  Mesh textured_;  // the atlas, at the frame's positions
  std::vector<std::string> takes_;
  double worst_ = std::numeric_limits<double>::infinity();
};

void TextureRun::validate() {
  Tally total;
  for (std::size_t k = 0; k < takes_.size(); ++k) {
    std::size_t frames = 0;
    const Tally take = compare_take(k, &frames);
    total.error.add(take.error);
    total.silhouette += take.silhouette;
    total.compared += take.compared;
    table_ += fmt::format("| {} | {} | {} | {:.2f} | | {:.1f} % |\n", run_.label, takes_[k], frames,
                          take.error.psnr_db(),
                          100.0 * take.compared / std::max<std::int64_t>(1, take.silhouette));
  }
  table_ += fmt::format("| {} | all | | **{:.2f}** | {:.2f} | {:.1f} % |\n", run_.label,
                        total.error.psnr_db(), worst_,
                        100.0 * total.compared / std::max<std::int64_t>(1, total.silhouette));
  add_metrics(total);
}

// Take k's sampled frames, each rendered into every camera; the first take's middle frame
// pictured.
Tally TextureRun::compare_take(std::size_t k, std::size_t* frames_compared) {
  const std::string& take = takes_[k];
  const std::vector<int> frames = sample_frames(frame_count(take), ctx_.options.frames_per_take);
  *frames_compared = frames.size();
  Tally tally;
  for (int frame : frames) {
    const Mesh aligned = read_ply(input_ / take / (frame_name(frame) + ".ply"));
    if (aligned.num_vertices() != textured_.num_vertices()) {
      throw InputError(fmt::format("{}: {} vertices, the atlas has {}", take,
                                   aligned.num_vertices(), textured_.num_vertices()));
    }
    textured_.positions = aligned.positions;
    const cv::Mat image = read_texture(run_.dir / take / (frame_name(frame) + extension_));
    const bool picture = k == 0 && frame == frames[frames.size() / 2];
    const auto results = compare_frame(ctx_.session, textured_, image, cameras_, take, frame, picture);
    std::vector<cv::Mat> rows;
    for (std::size_t c = 0; c < results.size(); ++c) {
      const CameraResult& r = results[c];
      tally.error.add(r.error);
      tally.silhouette += r.silhouette;
      tally.compared += r.compared;
      if (r.error.values > 0) worst_ = std::min(worst_, r.error.psnr_db());
      // Cameras spread evenly around the rig.
      const std::size_t step = std::max<std::size_t>(1, cameras_.size() / ctx_.options.picture_cameras);
      if (!r.picture.empty() && c % step == 0 && rows.size() < std::size_t(ctx_.options.picture_cameras)) {
        rows.push_back(panel(r.picture, std::min(3 * ctx_.options.panel_width, r.picture.cols),
                             cv::INTER_AREA,
                             fmt::format("{} {}: captured | textured render | |difference| x4",
                                         cameras_[c].name, frame_name(frame))));
      }
    }
    if (!rows.empty()) add_pictures(rows, take, frame, image);
  }
  return tally;
}

// The frame's comparison (`rows`, one per pictured camera) and its baked texture.
void TextureRun::add_pictures(const std::vector<cv::Mat>& rows, const std::string& take, int frame,
                              const cv::Mat& image) {
  cv::Mat picture;
  cv::vconcat(rows, picture);
  Picture p;
  p.file = fmt::format("texture_{}.png", run_.label);
  p.caption = fmt::format("Texture ({} meshes), take {} frame {}: captured image, the aligned "
                          "mesh rendered with its baked texture, and their difference "
                          "(x4) inside the silhouette.",
                          run_.label, take, frame);
  write_image_atomic(ctx_.reports_dir / p.file, picture);
  report_.pictures.push_back(p);
  cv::Mat map;
  image.convertTo(map, CV_8UC3, 255.0);
  Picture m;
  m.file = fmt::format("texture_{}_map.png", run_.label);
  m.caption = fmt::format("The baked texture of that frame ({} meshes) in the template's atlas.",
                          run_.label);
  write_image_atomic(ctx_.reports_dir / m.file,
                     panel(map, std::min(ctx_.options.panel_width, map.cols), cv::INTER_AREA,
                           fmt::format("{} {}", take, frame_name(frame))));
  report_.pictures.push_back(m);
}

void TextureRun::add_metrics(const Tally& total) {
  std::vector<std::pair<std::string, int>> frames_per_take;
  for (const std::string& take : takes_) frames_per_take.emplace_back(take, frame_count(take));
  const double flicker = texture_flicker(run_.dir, extension_, frames_per_take, textured_);
  const json atlas = read_json(run_.dir / "atlas.json");
  const json& stage_report = stage_report_;
  const RunFolder& run = run_;
  std::vector<Metric>& metrics = report_.metrics;
  metrics.push_back({"psnr_db", total.error.psnr_db(), run.input,
                     "textured mesh rendered into the studio cameras vs the captured "
                     "images, inside the silhouette [dB]"});
  metrics.push_back({"psnr_worst_image_db", worst_, run.input,
                     "the worst single camera image of the sampled frames [dB]"});
  metrics.push_back({"silhouette_covered", double(total.compared) / std::max<std::int64_t>(1, total.silhouette),
                     run.input, "fraction of silhouette pixels the textured mesh covers"});
  metrics.push_back({"unseen_texels_pct", 100.0 * stage_report.at("unseen_fraction_mean").get<double>(),
                     run.input, "texels no camera saw (filled), mean over frames [%]"});
  metrics.push_back({"flicker_levels", flicker, run.input,
                     "mean change of a chart texel between consecutive frames [8-bit "
                     "levels]; shading changes with the pose too: compare with oracle"});
  metrics.push_back({"seam_rms_levels", stage_report.at("seam_rms_after").get<double>(), run.input,
                     "colour difference across chart seams after levelling [8-bit levels]"});
  metrics.push_back({"seconds_per_frame", stage_report.at("seconds_per_frame").get<double>(),
                     run.input, "texture stage time per frame (bake + write) [s]"});
  metrics.push_back({"atlas_stretch_l2", atlas.at("stretch_l2").get<double>(), run.input,
                     "area-weighted L2 stretch of the atlas (1: none)"});
  metrics.push_back({"atlas_charts", atlas.at("charts").get<double>(), run.input,
                     "charts in the atlas"});
}

}  // namespace

StageReport validate_texture(const ValidationContext& ctx) {
  StageReport report;
  report.stage = "texture";
  const std::vector<RunFolder> runs = run_folders(ctx.session, "texture", "report.json");
  if (runs.empty() || !fs::exists(ctx.session.ground_truth_dir() / "silhouettes")) {
    report.summary = "Skipped: no texture/ output, or no ground-truth silhouettes to compare with.";
    return report;
  }
  report.present = true;
  report.summary =
      "Each sampled frame's aligned mesh with its baked texture, rendered (unlit) into every studio "
      "camera and compared with the captured image inside the ground-truth silhouette (eroded by "
      "one pixel) where the render covers it; PSNR pools the squared error of all those pixels. "
      "The studio lights the performer, so the textures carry its shading: the render reproduces "
      "the capture without lighting it again.";
  const std::vector<Camera> cameras = read_colmap_model(ctx.session.calibration_dir());
  std::string table =
      "| input | take | frames | PSNR [dB] | worst image [dB] | silhouette covered |\n"
      "|---|---|---|---|---|---|\n";
  for (const RunFolder& run : runs) TextureRun(ctx, run, cameras, report, table).validate();
  report.details = table;
  return report;
}

}  // namespace fourd::validate
