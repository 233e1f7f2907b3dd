// fourd-import: a studio's own capture into a session folder.
#include <CLI/CLI.hpp>

#include "pipeline/core/command_line.h"
#include "pipeline/core/error.h"
#include "pipeline/core/files.h"
#include "pipeline/core/guarded.h"
#include "pipeline/core/log.h"
#include "stages/import/import.h"

namespace {

// "cam01=path" pairs of a repeatable option.
std::map<std::string, std::filesystem::path> camera_files(const std::vector<std::string>& pairs,
                                                          const char* option) {
  std::map<std::string, std::filesystem::path> out;
  for (const std::string& p : pairs) {
    const auto eq = p.find('=');
    if (eq == std::string::npos || eq == 0 || eq + 1 == p.size()) {
      throw fourd::UsageError(fmt::format("{} '{}': expected CAMERA=FILE", option, p));
    }
    if (!out.emplace(p.substr(0, eq), p.substr(eq + 1)).second) {
      throw fourd::UsageError(fmt::format("{}: camera {} is given twice", option, p.substr(0, eq)));
    }
  }
  return out;
}

// What the command line sets: the import's options and the values that become them.
struct CommandLine {
  fourd::import::ImportOptions o;
  std::vector<std::string> calibration, videos, video_for, plates, plate_for, meshes;
  std::string csv_pose = "world_from_camera", csv_intrinsics = "detect";
  bool verbose = false;
};

void add_calibration_options(CLI::App& app, CommandLine& c) {
  fourd::import::ImportOptions& o = c.o;
  auto* cal = app.add_option_group("Calibration");
  cal->add_option("--calibration", c.calibration,
                  "COLMAP model folder, OpenCV FileStorage file(s) (.yml/.yaml/.xml; several: one per "
                  "camera, or intrinsics + extrinsics), a .csv, or a .json/.yaml of K, dist, R, t");
  cal->add_option("--calibration-format", o.calibration.format, "auto, colmap, opencv, csv or json")
      ->capture_default_str();
  cal->add_option("--units", o.calibration.units,
                  "length unit of the calibration: m, cm or mm (default: the file's, else inferred from "
                  "the cameras' distance to their common centre)");
  cal->add_option("--camera-images", o.calibration.camera_images,
                  "COLMAP: globs on image NAMEs selecting one image per camera (default: the first "
                  "image of each COLMAP camera)");
  cal->add_option("--csv-pose", c.csv_pose,
                  "CSV: rx ry rz / tx ty tz are world_from_camera (the camera's pose, t its centre) or "
                  "camera_from_world")
      ->capture_default_str();
  cal->add_option("--csv-intrinsics", c.csv_intrinsics,
                  "CSV: detect (fx < 10 is normalised), normalised, or pixels")
      ->capture_default_str();
  cal->add_flag("--drop-higher-distortion", o.calibration.drop_higher_distortion,
                "import lenses with k3 or higher terms by dropping them (the session's model is k1 "
                "k2 p1 p2)");
  cal->add_option("--up", o.calibration.up,
                  "the calibration world's up axis: auto (from the cameras), none (keep the world), or "
                  "+x -x +y -y +z -z; the world is rotated so that it becomes +z")
      ->capture_default_str();
}

void add_frame_options(CLI::App& app, CommandLine& c) {
  fourd::import::ImportOptions& o = c.o;
  auto* frames = app.add_option_group("Frames");
  frames->add_option("--videos", c.videos,
                     "video files or folders of them, one per camera, named after the camera");
  frames->add_option("--video", c.video_for, "CAMERA=FILE: the video of one camera (repeatable)");
  frames->add_option("--images", o.images,
                     "image pattern instead of videos, e.g. 'raw/{camera}/img_{frame:04d}.jpg' or "
                     "'raw/{camera}/*.png' (sorted naturally)");
  frames->add_option("--take", o.takes,
                     "NAME, NAME=FIRST:LAST (source frames, inclusive; LAST may be empty) or "
                     "NAME=FROMs:TOs (seconds); repeatable: several takes from one recording");
  frames->add_option("--start", o.start, "first source frame of a take given without range")
      ->check(CLI::NonNegativeNumber)->capture_default_str();
  frames->add_option("--end", o.end, "last source frame (inclusive; -1: the end)")->capture_default_str();
  frames->add_option("--step", o.step, "keep every STEP-th frame")->check(CLI::PositiveNumber)->capture_default_str();
  frames->add_option("--from-time", o.from_time, "start of a take given without range [s]")
      ->check(CLI::NonNegativeNumber);
  frames->add_option("--to-time", o.to_time, "end of a take given without range [s]")->check(CLI::PositiveNumber);
  frames->add_option("--fps", o.fps, "frame rate (default: the videos', else session.yaml's, else 25)")
      ->check(CLI::NonNegativeNumber);
}

void add_extra_options(CLI::App& app, CommandLine& c) {
  fourd::import::ImportOptions& o = c.o;
  auto* extra = app.add_option_group("Plates, masks, meshes");
  extra->add_option("--plates", c.plates,
                    "images or videos of the empty studio (files or folders), named after the camera");
  extra->add_option("--plate", c.plate_for, "CAMERA=FILE: the plate of one camera (repeatable)");
  extra->add_option("--plate-frames", o.plate_frames, "frames sampled evenly from a plate video")
      ->check(CLI::Range(1, 100000))->capture_default_str();
  extra->add_option("--masks", o.masks, "mask image pattern like --images (same frame selection)");
  extra->add_option("--mask-threshold", o.mask_threshold,
                    "mask values above this become 255 (soft mattes: e.g. 127)")
      ->check(CLI::Range(0, 254))->capture_default_str();
  extra->add_option("--meshes", c.meshes, "per-frame .ply/.obj files or folders of them, in frame order");
  extra->add_flag("--consistent", o.consistent,
                  "the meshes share one topology: import them as align/ (template.ply + frames)");
  extra->add_option("--mesh-units", o.mesh_units, "m, cm or mm (default: inferred from the extent)");
}

void add_export_options(CLI::App& app, CommandLine& c) {
  fourd::import::ImportOptions& o = c.o;
  std::string export_formats;
  for (const auto& f : fourd::import::export_formats()) export_formats += (export_formats.empty() ? "" : ", ") + f;
  auto* out = app.add_option_group("Export");
  out->add_option("--export-calibration", o.export_format,
                  "write the session's calibration in a foreign format instead: " + export_formats);
  out->add_option("--output", o.export_path, "file or folder the export writes");
  out->add_option("--export-units", o.export_units, "length unit of the export: m, cm or mm")
      ->capture_default_str();
}

// The command line's values turned into the import's options.
void finish_options(CommandLine& c) {
  using namespace fourd;
  import::ImportOptions& o = c.o;
  for (const auto& p : c.calibration) o.calibration.paths.emplace_back(p);
  for (const auto& v : c.videos) o.videos.emplace_back(v);
  for (const auto& p : c.plates) o.plates.emplace_back(p);
  for (const auto& m : c.meshes) o.meshes.emplace_back(m);
  o.video_for = camera_files(c.video_for, "--video");
  o.plate_for = camera_files(c.plate_for, "--plate");
  if (c.csv_pose == "world_from_camera") {
    o.calibration.csv.pose = CsvPose::kWorldFromCamera;
  } else if (c.csv_pose == "camera_from_world") {
    o.calibration.csv.pose = CsvPose::kCameraFromWorld;
  } else {
    throw UsageError(fmt::format("--csv-pose '{}': world_from_camera or camera_from_world", c.csv_pose));
  }
  if (c.csv_intrinsics == "detect") {
    o.calibration.csv.intrinsics = CsvIntrinsics::kDetect;
  } else if (c.csv_intrinsics == "normalised" || c.csv_intrinsics == "normalized") {
    o.calibration.csv.intrinsics = CsvIntrinsics::kNormalised;
  } else if (c.csv_intrinsics == "pixels") {
    o.calibration.csv.intrinsics = CsvIntrinsics::kPixels;
  } else {
    throw UsageError(fmt::format("--csv-intrinsics '{}': detect, normalised or pixels", c.csv_intrinsics));
  }
}

}  // namespace

int main(int argc, char** argv) {
  using namespace fourd;
  CommandLine c;
  import::ImportOptions& o = c.o;
  CLI::App app{
      "Creates or extends a session folder from a studio's capture: the calibration in a foreign "
      "format becomes calibration/ (COLMAP text model, metres, z up), one video or image folder per "
      "camera becomes capture/<take>/<camera>/<frame>.png, background plates plates/<camera>/, masks "
      "masks/<take>/<camera>/, per-frame meshes reconstruct/<take>/ (or align/ with --consistent). "
      "Every folder written gets imported.json. Nothing is changed when anything is wrong.",
      "fourd-import"};
  app.add_option("session", o.session, "session folder (created when missing)")->required();
  app.add_option("--name", o.name, "name of a new session (default: the folder's name)");
  app.add_flag("--replace", o.replace, "replace folders and takes that exist");
  app.add_flag("-v,--verbose", c.verbose, "debug messages");
  add_calibration_options(app, c);
  add_frame_options(app, c);
  add_extra_options(app, c);
  add_export_options(app, c);

  if (const auto code = parse_command_line(app, argc, argv)) return *code;
  if (c.verbose) log::set_level(log::Level::kDebug);
  const int code = run_guarded("fourd-import", [&]() -> int {
    finish_options(c);
    if (o.export_format.empty()) {
      ensure_directory(o.session / "logs");
      log::open_file(o.session / "logs" / "import.log");
    }
    log::info("fourd-import on {}", o.session.string());
    log::Timer timer;
    import::run_import(o);
    log::info("fourd-import finished in {:.1f} s ({} warnings)", timer.seconds(), log::warning_count());
    return kExitOk;
  });
  log::open_file({});
  return code;
}
