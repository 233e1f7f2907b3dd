#include "stages/import/import.h"

#include <fmt/format.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <atomic>
#include <memory>
#include <mutex>
#include <nlohmann/json.hpp>
#include <set>
#include <sstream>

#include "pipeline/core/colmap_model.h"
#include "pipeline/core/error.h"
#include "pipeline/core/files.h"
#include "pipeline/core/image_io.h"
#include "pipeline/core/log.h"
#include "pipeline/core/session.h"
#include "pipeline/core/staged_folder.h"
#include "stages/import/media.h"
#include "stages/import/meshes.h"

namespace fourd::import {
namespace {

namespace fs = std::filesystem;
using json = nlohmann::json;

std::string relative_to(const fs::path& p, const fs::path&) {
  std::error_code ec;
  const fs::path abs = fs::absolute(p, ec);
  return ec ? p.string() : abs.lexically_normal().string();
}

// The folders of one import: each is staged beside its final place and renamed into place by
// commit(), after every check passed; folders the import had to create for them (capture/ for
// capture/<take>) are removed again when it fails.
class Outputs {
 public:
  Outputs(fs::path root, bool replace) : root_(std::move(root)), replace_(replace) {}
  ~Outputs() {
    if (committed_) return;
    staged_.clear();  // removes the staging folders
    std::sort(created_.begin(), created_.end(), [](const fs::path& a, const fs::path& b) {
      return a.string().size() > b.string().size();  // the deepest first
    });
    for (const fs::path& dir : created_) {
      std::error_code ec;
      fs::remove(dir, ec);  // only when empty
    }
  }

  // The staging folder of <root>/<relative>; an existing target is an error unless replacing.
  fs::path stage(const fs::path& relative) {
    const fs::path target = root_ / relative;
    if (fs::exists(target) && !replace_) {
      throw UsageError(fmt::format("{} exists: pass --replace to replace it", target.string()));
    }
    for (fs::path p = target.parent_path(); p != root_ && !p.empty() && !fs::exists(p); p = p.parent_path()) {
      if (std::find(created_.begin(), created_.end(), p) == created_.end()) created_.push_back(p);
    }
    staged_.push_back(std::make_unique<StagedFolder>(target));
    return staged_.back()->path();
  }

  // Renames every staged folder into place.
  void commit() {
    for (auto& s : staged_) s->commit();
    committed_ = true;
  }

 private:
  fs::path root_;
  bool replace_;
  std::vector<std::unique_ptr<StagedFolder>> staged_;
  std::vector<fs::path> created_;
  bool committed_ = false;
};

// <dir>/imported.json, merged with the record of an earlier import into the same folder (other
// takes), written atomically.
void write_record(const fs::path& dir, const std::string& what, const std::vector<std::string>& sources,
                  const json& takes, const json& checks) {
  json record = {{"tool", "fourd-import"}, {"what", what}, {"source", json::array()},
                 {"takes", json::object()}, {"checks", json::object()}};
  const fs::path file = dir / kImportRecordFile;
  if (fs::exists(file)) {
    try {
      const json previous = json::parse(read_file(file));
      if (previous.value("tool", "") == "fourd-import" && previous.value("what", "") == what) record = previous;
    } catch (const json::exception&) {
      // an unreadable record is replaced
    }
  }
  for (const std::string& s : sources) {
    if (std::find(record["source"].begin(), record["source"].end(), s) == record["source"].end()) {
      record["source"].push_back(s);
    }
  }
  if (takes.is_object()) {
    for (const auto& [k, v] : takes.items()) record["takes"][k] = v;
  } else {
    record["takes"] = takes;
  }
  for (const auto& [k, v] : checks.items()) record["checks"][k] = v;
  record["imported_at"] = log::local_time();
  write_file_atomic(file, record.dump(1) + "\n");
}

std::string join(const std::vector<std::string>& items) {
  std::string out;
  for (const auto& s : items) out += (out.empty() ? "" : ", ") + s;
  return out;
}

const Camera& camera_named(const std::vector<Camera>& cameras, const std::string& name) {
  for (const Camera& c : cameras) {
    if (c.name == name) return c;
  }
  throw InputError(fmt::format("no camera {}", name));
}

void check_size(const cv::Mat& image, const Camera& camera, const std::string& what) {
  if (image.cols != camera.intrinsics.width || image.rows != camera.intrinsics.height) {
    throw InputError(fmt::format("{}: {}x{}, but camera {} is calibrated at {}x{}", what, image.cols,
                                 image.rows, camera.name, camera.intrinsics.width, camera.intrinsics.height));
  }
}

std::string frame_source(const Sequence& s, int source) {
  if (!s.video.empty()) return fmt::format("{} frame {}", s.video.string(), source);
  return s.images[static_cast<std::size_t>(source)].string();
}

// How many frames each take got: a closed range its own; an open one the shortest camera's.
std::vector<int> take_counts(const std::vector<TakeSpec>& takes, const std::vector<int>& sequence_lengths) {
  std::vector<int> counts;
  const int shortest = *std::min_element(sequence_lengths.begin(), sequence_lengths.end());
  for (const TakeSpec& t : takes) {
    const int last = t.last >= 0 ? t.last : shortest - 1;
    counts.push_back(last < t.first ? 0 : (last - t.first) / t.step + 1);
  }
  return counts;
}

// The takes as closed ranges, now that their frame counts are known.
std::vector<TakeSpec> closed(std::vector<TakeSpec> takes, const std::vector<int>& counts) {
  for (std::size_t k = 0; k < takes.size(); ++k) takes[k].last = takes[k].first + (counts[k] - 1) * takes[k].step;
  return takes;
}

json takes_json(const std::vector<TakeSpec>& takes, const std::vector<int>& counts) {
  json out = json::object();
  for (std::size_t k = 0; k < takes.size(); ++k) {
    out[takes[k].name] = {{"frames", counts[k]}, {"source_first", takes[k].first},
                          {"source_last", takes[k].first + (counts[k] - 1) * takes[k].step},
                          {"step", takes[k].step}};
  }
  return out;
}

// Frames (or masks) of every camera into <staged take>/<camera>/<frame>.png. `mask_threshold`
// >= 0: single-channel masks, binarised. Returns each take's frame count.
std::vector<int> write_sequences(const std::vector<Camera>& cameras, const std::map<std::string, Sequence>& sequences,
                                 const std::vector<TakeSpec>& takes, const std::vector<fs::path>& take_dirs,
                                 int mask_threshold, const std::string& what) {
  const bool masks = mask_threshold >= 0;
  std::vector<int> lengths(cameras.size());
  std::vector<std::vector<int>> written(cameras.size(), std::vector<int>(takes.size(), 0));
  log::Progress progress(what + " (cameras)", cameras.size(), 5.0);
  std::mutex error_mutex;
  std::exception_ptr error;
  tbb::parallel_for(std::size_t{0}, cameras.size(), [&](std::size_t c) {
    try {
      const Camera& camera = cameras[c];
      const Sequence& sequence = sequences.at(camera.name);
      log::Timer timer;
      lengths[c] = read_sequence(sequence, takes, masks ? cv::IMREAD_GRAYSCALE : cv::IMREAD_COLOR,
                                 [&](std::size_t k, int frame, int source, const cv::Mat& image) {
        const std::string label = fmt::format("{} (camera {}, take {} frame {})", frame_source(sequence, source),
                                              camera.name, takes[k].name, frame_name(frame));
        check_size(image, camera, label);
        cv::Mat out = image;
        if (masks) {
          if (image.channels() != 1) cv::extractChannel(image, out, 0);
          out = out > mask_threshold;  // 0/255
        }
        write_image_atomic(take_dirs[k] / camera.name / (frame_name(frame) + ".png"), out,
                           {cv::IMWRITE_PNG_COMPRESSION, 1});
        ++written[c][k];
      });
      int total = 0;
      for (int n : written[c]) total += n;
      log::info("{} camera {}: {} frames from {} ({} source frames read, {:.1f} s)", what, camera.name, total,
                sequence.describe(), lengths[c], timer.seconds());
      progress.step();
    } catch (...) {
      std::lock_guard<std::mutex> lock(error_mutex);
      if (!error) error = std::current_exception();
    }
  });
  if (error) std::rethrow_exception(error);
  std::vector<int> counts = take_counts(takes, lengths);
  // Open ranges stop at the shortest camera: drop what the longer ones wrote beyond it.
  for (std::size_t k = 0; k < takes.size(); ++k) {
    for (std::size_t c = 0; c < cameras.size(); ++c) {
      if (written[c][k] > counts[k]) {
        log::warn("take {}: camera {} has {} frames, the shortest camera {}: the take keeps {}", takes[k].name,
                  cameras[c].name, written[c][k], counts[k], counts[k]);
        for (int f = counts[k]; f < written[c][k]; ++f) fs::remove(take_dirs[k] / cameras[c].name / (frame_name(f) + ".png"));
      }
    }
    if (counts[k] == 0) throw InputError(fmt::format("take {}: no frames selected", takes[k].name));
  }
  return counts;
}

std::map<std::string, Sequence> pattern_sequences(const std::string& pattern, const std::vector<Camera>& cameras) {
  std::map<std::string, Sequence> out;
  for (const Camera& c : cameras) out[c.name] = Sequence{c.name, {}, images_from_pattern(pattern, c.name)};
  return out;
}

// The frames of a take an earlier import or synth wrote: capture/<take>/<first camera>/.
int existing_take_frames(const Session& session, const std::string& take, const std::string& camera) {
  int n = 0;
  while (fs::exists(session.capture_image(take, camera, n))) ++n;
  return n;
}

std::string session_yaml(const std::string& name, double fps, const std::vector<std::string>& takes) {
  std::string out = fmt::format(
      "# Made by fourd-import. Imported takes: {}.\n"
      "name: {}\n"
      "fps: {}\n\n"
      "# Motion classes: group the takes of one kind of motion (2 or 3 takes each, in parameter\n"
      "# order) for timewarp, motionspace and graph, e.g.\n",
      takes.empty() ? std::string("none yet") : join(takes), name, fps);
  out += fmt::format("#   - {{name: locomotion, takes: [{}], parameter: speed, cyclic: true}}\n",
                     join(std::vector<std::string>(takes.begin(), takes.begin() + std::min<std::size_t>(2, takes.size()))));
  out += "motions: []\n";
  return out;
}

void export_only(const ImportOptions& options) {
  if (options.export_path.empty()) throw UsageError("--export-calibration needs --output PATH");
  const std::vector<Camera> cameras = read_colmap_model(options.session / "calibration");
  const LengthUnit unit = parse_length_unit(options.export_units, "--units");
  export_calibration(cameras, options.export_format, options.export_path, unit);
  log::info("wrote the calibration of {} cameras as {} ({}) to {}", cameras.size(), options.export_format,
            unit_name(unit), options.export_path.string());
}

// The request checked before anything is written: something to import, in a form that fits.
void check_request(const ImportOptions& options, bool frames_wanted) {
  const bool anything = !options.calibration.paths.empty() || frames_wanted || !options.plates.empty() ||
                        !options.plate_for.empty() || !options.masks.empty() || !options.meshes.empty();
  if (!anything) throw UsageError("nothing to import: give --calibration, --videos/--images, --plates, --masks or --meshes");
  if (!options.videos.empty() && !options.images.empty()) throw UsageError("give --videos or --images, not both");
  if (options.takes.empty() && (frames_wanted || !options.masks.empty() || !options.meshes.empty())) {
    throw UsageError("frames, masks and meshes go into takes: give --take NAME[=FIRST:LAST] (repeatable)");
  }
}

// One import's steps, in order, and what they hand each other: the cameras, the takes and their
// frame counts, the staged folders and the records written once every step passed.
class Import {
 public:
  Import(const ImportOptions& options, bool frames_wanted)
      : options_(options),
        root_(options.session),
        frames_wanted_(frames_wanted),
        new_session_(!fs::exists(root_ / "session.yaml")),
        session_(new_session_ ? std::nullopt : std::optional<Session>(Session::open(root_))),
        outputs_(root_, options.replace) {}

  void calibration();         // 1.
  void takes_and_frames();    // 2.
  void plates();              // 3.
  void masks();               // 4.
  void meshes();              // 5.
  void session_and_commit();  // 6. and the commit

 private:
  struct Record {
    fs::path dir;
    std::string what;
    std::vector<std::string> sources;
    json takes, checks;
  };
  void import_calibration_files();
  std::vector<std::string> frame_sources(std::map<std::string, Sequence>& sequences);
  void take_fps_from_videos(const std::map<std::string, Sequence>& sequences);

  const ImportOptions& options_;
  const fs::path root_;
  const bool frames_wanted_;
  const bool new_session_;
  const std::optional<Session> session_;
  Outputs outputs_;
  std::vector<Record> records_;
  std::vector<Camera> cameras_;
  Eigen::Matrix3d world_rotation_ = Eigen::Matrix3d::Identity();
  std::optional<Eigen::Vector3d> volume_centre_;
  std::vector<TakeSpec> takes_;
  std::set<std::string> take_names_;
  double fps_ = 0;
  std::vector<int> counts_;  // per take, once known
};

// 1. Calibration: imported, or the session's.
void Import::calibration() {
  if (!options_.calibration.paths.empty()) {
    import_calibration_files();
  } else if (fs::exists(root_ / "calibration")) {
    cameras_ = read_colmap_model(root_ / "calibration");
    volume_centre_ = rig_geometry(cameras_).centre;
    log::info("calibration: the session's, {} cameras", cameras_.size());
  } else if (frames_wanted_ || !options_.plates.empty() || !options_.masks.empty()) {
    throw UsageError(fmt::format("{}: no calibration/ yet: give --calibration", root_.string()));
  }
}

void Import::import_calibration_files() {
  const ImportedCalibration imported = import_calibration(options_.calibration);
  cameras_ = imported.cameras;
  world_rotation_ = imported.world_rotation;
  volume_centre_ = imported.geometry.centre;
  log::info("calibration: {} cameras read as {} ({})", cameras_.size(), detect_format(options_.calibration),
            imported.convention);
  log::info("calibration: lengths in {}, {}", unit_name(imported.unit), imported.unit_origin);
  log::info("calibration: up axis {}; {}", imported.up_axis, imported.world_change);
  for (const auto& n : imported.notes) log::warn("calibration: {}", n);
  for (const auto& w : imported.warnings) log::warn("calibration: {}", w);
  const Eigen::Vector3d& c = imported.geometry.centre;
  log::info("calibration: the cameras look at ({:.3f}, {:.3f}, {:.3f}) m\n{}", c.x(), c.y(), c.z(),
            summary_table(cameras_, imported.geometry));
  const fs::path staged = outputs_.stage("calibration");
  write_colmap_model(staged, cameras_);
  json per_camera = json::array();
  for (std::size_t i = 0; i < cameras_.size(); ++i) {
    per_camera.push_back({{"name", cameras_[i].name}, {"distance_m", imported.geometry.distance[i]},
                          {"sees_common_centre", static_cast<bool>(imported.geometry.sees[i])}});
  }
  std::vector<std::string> sources;
  for (const auto& p : options_.calibration.paths) sources.push_back(relative_to(p, root_));
  json world = json::array();
  for (int r = 0; r < 3; ++r) world.push_back({world_rotation_(r, 0), world_rotation_(r, 1), world_rotation_(r, 2)});
  records_.push_back({root_ / "calibration", "calibration", sources, json(nullptr),
                      {{"format", detect_format(options_.calibration)},
                       {"convention", imported.convention},
                       {"units", unit_name(imported.unit)},
                       {"unit_origin", imported.unit_origin},
                       {"up_axis", imported.up_axis},
                       {"world_change", imported.world_change},
                       {"session_from_file_rotation", world},
                       {"common_centre_m", {c.x(), c.y(), c.z()}},
                       {"cameras", per_camera},
                       {"warnings", imported.warnings}}});
}

// 2. Takes and frames.
void Import::takes_and_frames() {
  for (const std::string& t : options_.takes) {
    takes_.push_back(parse_take(t, options_.start, options_.end, options_.step, options_.from_time, options_.to_time));
    if (!take_names_.insert(takes_.back().name).second) throw UsageError(fmt::format("--take {} is given twice", takes_.back().name));
  }
  fps_ = options_.fps > 0 ? options_.fps : session_ ? session_->config().fps : 0.0;
  if (frames_wanted_) {
    std::map<std::string, Sequence> sequences;
    const std::vector<std::string> sources = frame_sources(sequences);
    for (TakeSpec& t : takes_) t = resolve_times(t, fps_);
    std::vector<fs::path> take_dirs;
    for (const TakeSpec& t : takes_) take_dirs.push_back(outputs_.stage(fs::path("capture") / t.name));
    log::info("frames: {} cameras, takes {}", cameras_.size(), join(std::vector<std::string>(take_names_.begin(), take_names_.end())));
    log::Timer timer;
    counts_ = write_sequences(cameras_, sequences, takes_, take_dirs, -1, "frames");
    int total = 0;
    for (int n : counts_) total += n;
    log::info("frames: {} frames x {} cameras in {:.1f} s ({:.1f} ms per image)", total, cameras_.size(),
              timer.seconds(), 1000 * timer.seconds() / std::max(1, total * static_cast<int>(cameras_.size())));
    takes_ = closed(takes_, counts_);
    records_.push_back({root_ / "capture", "capture", sources, takes_json(takes_, counts_),
                        {{"cameras", cameras_.size()}, {"fps", fps_}, {"frame_sizes_match_calibration", true}}});
  } else if (!takes_.empty()) {
    for (TakeSpec& t : takes_) t = resolve_times(t, fps_);
    // Masks or meshes of takes captured before: their frames are the capture's.
    if (session_ && !cameras_.empty()) {
      for (TakeSpec& t : takes_) {
        const int n = existing_take_frames(*session_, t.name, cameras_.front().name);
        if (n > 0 && t.last < 0 && t.first == 0 && t.step == 1) t.last = n - 1;
      }
    }
  }
}

// Every camera's image sequence or video; returns the sources for the record.
std::vector<std::string> Import::frame_sources(std::map<std::string, Sequence>& sequences) {
  std::vector<std::string> sources;
  if (!options_.images.empty()) {
    sequences = pattern_sequences(options_.images, cameras_);
    sources.push_back(options_.images);
    return sources;
  }
  const auto matched = match_files_to_cameras(list_files(options_.videos, video_extensions()), options_.video_for,
                                              cameras_, "video");
  for (const auto& [camera, files] : matched) {
    sequences[camera] = Sequence{camera, files.front(), {}};
    sources.push_back(relative_to(files.front(), root_));
  }
  if (options_.fps <= 0) take_fps_from_videos(sequences);
  return sources;
}

// The frame rate of the videos (warned about when they or session.yaml disagree).
void Import::take_fps_from_videos(const std::map<std::string, Sequence>& sequences) {
  const double video_rate = video_fps(sequences.begin()->second.video, sequences.begin()->first);
  for (const auto& [camera, s] : sequences) {
    const double r = video_fps(s.video, camera);
    if (std::abs(r - video_rate) > 1e-3 * video_rate) {
      log::warn("video {} (camera {}) runs at {:.3f} fps, {} at {:.3f}", s.video.string(), camera, r,
                sequences.begin()->second.video.string(), video_rate);
    }
  }
  if (video_rate > 0) {
    if (session_ && std::abs(video_rate - session_->config().fps) > 1e-3) {
      log::warn("the videos run at {:.3f} fps, session.yaml says fps {}", video_rate, session_->config().fps);
    }
    fps_ = video_rate;
  }
}

// 3. Background plates.
void Import::plates() {
  if (options_.plates.empty() && options_.plate_for.empty()) return;
  std::vector<std::string> extensions = image_extensions();
  extensions.insert(extensions.end(), video_extensions().begin(), video_extensions().end());
  const auto matched = match_files_to_cameras(list_files(options_.plates, extensions), options_.plate_for, cameras_,
                                              "plate", /*several=*/true);
  const fs::path staged = outputs_.stage("plates");
  std::vector<std::string> sources;
  json per_camera = json::object();
  for (const auto& [camera_name, files] : matched) {
    const Camera& camera = camera_named(cameras_, camera_name);
    int index = 0;
    for (const fs::path& file : files) {
      sources.push_back(relative_to(file, root_));
      std::vector<cv::Mat> images;
      if (is_video_file(file)) {
        images = sample_video(file, camera_name, options_.plate_frames);
      } else {
        images.push_back(read_image(file));
      }
      for (const cv::Mat& image : images) {
        check_size(image, camera, fmt::format("plate {} (camera {})", file.string(), camera_name));
        write_image_atomic(staged / camera_name / (frame_name(index++) + ".png"), image);
      }
    }
    per_camera[camera_name] = index;
    log::info("plates camera {}: {} images", camera_name, index);
  }
  records_.push_back({root_ / "plates", "plates", sources, json(nullptr), {{"plates_per_camera", per_camera}}});
}

// 4. Masks.
void Import::masks() {
  if (options_.masks.empty()) return;
  std::vector<fs::path> take_dirs;
  for (const TakeSpec& t : takes_) take_dirs.push_back(outputs_.stage(fs::path("masks") / t.name));
  const std::vector<int> mask_counts = write_sequences(cameras_, pattern_sequences(options_.masks, cameras_), takes_,
                                                       take_dirs, options_.mask_threshold, "masks");
  if (!counts_.empty() && mask_counts != counts_) {
    throw InputError(fmt::format("--masks {}: the masks give takes other frame counts than the frames", options_.masks));
  }
  records_.push_back({root_ / "masks", "masks", {options_.masks}, takes_json(takes_, mask_counts),
                      {{"threshold", options_.mask_threshold}, {"values", "0/255"}, {"sizes_match_calibration", true}}});
}

// 5. Meshes: as reconstruct's output, or with --consistent as align's.
void Import::meshes() {
  if (options_.meshes.empty()) return;
  MeshImportOptions mesh_options;
  mesh_options.units = options_.mesh_units;
  mesh_options.consistent = options_.consistent;
  mesh_options.world_rotation = world_rotation_;
  mesh_options.volume_centre = volume_centre_;
  const std::vector<fs::path> files = list_files(options_.meshes, {".ply", ".obj"});
  std::vector<fs::path> take_dirs;
  fs::path template_file;
  if (options_.consistent) {
    const fs::path out = outputs_.stage("align");
    template_file = out / "template.ply";
    for (const TakeSpec& t : takes_) take_dirs.push_back(out / t.name);
  } else {
    for (const TakeSpec& t : takes_) take_dirs.push_back(outputs_.stage(fs::path("reconstruct") / t.name));
  }
  const MeshImportResult result = import_meshes(files, takes_, mesh_options, take_dirs, template_file);
  log::info("meshes: {} frames, lengths in {} ({}){}", result.check.frames, unit_name(result.unit),
            result.unit_origin, world_rotation_.isIdentity() ? "" : ", rotated with the calibration's world");
  for (const auto& w : result.warnings) log::warn("meshes: {}", w);
  json takes_record = json::object();
  for (const auto& [take, n] : result.frames) takes_record[take] = {{"frames", n}};
  json checks = {{"units", unit_name(result.unit)}, {"unit_origin", result.unit_origin},
                 {"manifold", result.check.to_json()}, {"consistent_topology", options_.consistent},
                 {"confidence", "none (not from fourd-reconstruct)"}};
  std::vector<std::string> sources;
  for (const auto& p : options_.meshes) sources.push_back(relative_to(p, root_));
  const std::string what = options_.consistent ? "align" : "reconstruct";
  records_.push_back({root_ / what, what, sources, takes_record, checks});
}

// 6. session.yaml for a new session (takes in no motion class of an existing one warned
// about); then everything checked and written goes into place, then the records, then
// session.yaml.
void Import::session_and_commit() {
  std::vector<std::string> names;
  for (const TakeSpec& t : takes_) names.push_back(t.name);
  std::string yaml_text;
  if (new_session_) {
    const std::string name = options_.name.empty() ? fs::absolute(root_).lexically_normal().filename().string() : options_.name;
    yaml_text = session_yaml(name.empty() ? "session" : name, fps_ > 0 ? fps_ : 25, names);
  } else if (session_) {
    std::set<std::string> declared;
    for (const auto& m : session_->config().motions) declared.insert(m.takes.begin(), m.takes.end());
    for (const std::string& t : names) {
      if (!declared.count(t)) log::warn("take {} is in no motion class of session.yaml (motions:): add it to one", t);
    }
  }

  outputs_.commit();
  for (const Record& r : records_) write_record(r.dir, r.what, r.sources, r.takes, r.checks);
  if (new_session_) {
    write_file_atomic(root_ / "session.yaml", yaml_text);
    log::info("wrote {} (motion classes left for you to declare)", (root_ / "session.yaml").string());
  }
}

}  // namespace

void run_import(const ImportOptions& options) {
  if (!options.export_format.empty()) {
    export_only(options);
    return;
  }
  const bool frames_wanted = !options.videos.empty() || !options.video_for.empty() || !options.images.empty();
  check_request(options, frames_wanted);
  ensure_directory(options.session);
  Import import(options, frames_wanted);
  import.calibration();
  import.takes_and_frames();
  import.plates();
  import.masks();
  import.meshes();
  import.session_and_commit();
}

}  // namespace fourd::import
