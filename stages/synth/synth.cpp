#include "stages/synth/synth.h"

#include <tbb/parallel_for.h>

#include <Eigen/Geometry>
#include <nlohmann/json.hpp>
#include <random>
#include <set>

#include "pipeline/core/colmap_model.h"
#include "pipeline/core/error.h"
#include "pipeline/core/files.h"
#include "pipeline/core/image_io.h"
#include "pipeline/core/log.h"
#include "pipeline/core/mesh_io.h"
#include "pipeline/core/staged_folder.h"
#include "stages/synth/garment.h"

namespace fourd::synth {
namespace {

// Written into capture/ so that a rerun never overwrites a real studio capture.
constexpr const char* kSyntheticMarker = ".synthetic";

// The room studio (backdrop "room"): plates of the empty room per camera, each with its own
// sensor noise, as a studio shoots a few frames of the empty set before a take; and the lights'
// flicker, a global gain per frame uniform within +-kFlicker (mains-powered lights).
constexpr int kPlates = 3;
constexpr double kFlicker = 0.03;

std::uint64_t mix_seed(std::uint64_t seed, const std::string& what, int a = 0, int b = 0) {
  std::string key = fmt::format("{}|{}|{}|{}", seed, what, a, b);
  return hash_bytes(key);
}

// The calibration a studio would hand us: the true cameras, optionally perturbed.
std::vector<Camera> perturb_calibration(const std::vector<Camera>& rig, const CalibrationNoise& noise,
                                        std::uint64_t seed) {
  std::vector<Camera> out = rig;
  if (!noise.any()) return out;
  std::mt19937_64 rng(mix_seed(seed, "calibration_noise"));
  std::normal_distribution<double> n01(0.0, 1.0);
  for (Camera& cam : out) {
    Eigen::Vector3d axis(n01(rng), n01(rng), n01(rng));
    double angle = noise.rotation_deg * M_PI / 180.0 * n01(rng);
    Eigen::Matrix3d dR = Eigen::AngleAxisd(angle, axis.normalized()).toRotationMatrix();
    Eigen::Vector3d dt = Eigen::Vector3d(n01(rng), n01(rng), n01(rng)) * noise.translation_mm * 1e-3;
    Eigen::Isometry3d perturbed = Eigen::Isometry3d::Identity();
    perturbed.linear() = dR * cam.camera_from_world.linear();
    perturbed.translation() = dR * cam.camera_from_world.translation() + dt;
    cam.camera_from_world = perturbed;
    double f = 1.0 + noise.focal_pct / 100.0 * n01(rng);
    cam.intrinsics.fx *= f;
    cam.intrinsics.fy *= f;
  }
  return out;
}

void write_json(const fs::path& path, const nlohmann::json& j) {
  write_file_atomic(path, j.dump(1) + "\n");
}

// The motions' parameters in metres (or metres per second), which scale with the scene.
bool is_length_parameter(const std::string& name) {
  return name == "speed" || name == "jump_length" || name == "jump_height" ||
         name == "reach_x" || name == "reach_y" || name == "reach_z";
}

std::vector<double> scaled(std::vector<double> v, double s) {
  for (double& x : v) x *= s;
  return v;
}

// The cameras of a scene `s` times the size: the same orientations and intrinsics, centres
// `s` times as far from the origin (the same images).
std::vector<Camera> scaled_cameras(std::vector<Camera> cameras, double s) {
  for (Camera& c : cameras) c.camera_from_world.translation() *= s;
  return cameras;
}

Mesh scaled_mesh(Mesh mesh, double s) {
  for (Vec3f& p : mesh.positions) p *= static_cast<float>(s);
  return mesh;
}

nlohmann::json take_json(const MotionClip& clip, double s) {
  nlohmann::json j;
  j["take"] = clip.spec.take;
  j["kind"] = clip.spec.kind;
  j["fps"] = clip.fps;
  j["frames"] = clip.poses.size();
  j["cycle_frames"] = clip.cycle_frames;
  j["spec"] = {{"take", clip.spec.take},
               {"kind", clip.spec.kind},
               {"frames", clip.spec.frames},
               {"speed", clip.spec.speed * s},
               {"turn_rate", clip.spec.turn_rate},
               {"jump_length", clip.spec.jump_length * s},
               {"jump_height", clip.spec.jump_height * s},
               {"reach_target", scaled(clip.spec.reach_target, s)},
               {"start_heading", clip.spec.start_heading},
               {"start_position", scaled(clip.spec.start_position, s)},
               {"start_phase", clip.spec.start_phase}};
  if (!clip.spec.pauses.empty()) {
    nlohmann::json pauses = nlohmann::json::array();
    for (const PauseSpec& p : clip.spec.pauses) pauses.push_back({{"at", p.at}, {"frames", p.frames}});
    j["spec"]["pauses"] = pauses;
    j["amplitude"] = clip.amplitude;
  }
  nlohmann::json params = nlohmann::json::object();
  for (const auto& [name, value] : clip.parameters) {
    params[name] = is_length_parameter(name) ? value * s : value;
  }
  j["parameters"] = params;
  nlohmann::json root = nlohmann::json::array();
  for (const RootState& r : clip.root) {
    root.push_back({r.position.x() * s, r.position.y() * s, r.heading});
  }
  j["root"] = root;
  j["phase"] = clip.phase;
  return j;
}

nlohmann::json character_json(const Character& character, const Mesh& surface, double s) {
  nlohmann::json j;
  j["name"] = character.name;
  j["height"] = character.height * s;
  j["vertices"] = surface.num_vertices();
  j["triangles"] = surface.num_triangles();
  if (character.garment) {
    // The garment's vertices follow the skin's in every mesh.
    const Garment& g = *character.garment;
    j["garment"] = {{"kind", "skirt"},
                    {"first_vertex", character.skin.rest.num_vertices()},
                    {"vertices", g.rest.num_vertices()},
                    {"rings", g.grid.rings},
                    {"columns", g.grid.columns},
                    {"length", g.length * s},
                    {"flare_deg", g.flare * 180 / M_PI},
                    {"thickness", g.thickness * s}};
  }
  nlohmann::json joints = nlohmann::json::array();
  for (std::size_t i = 0; i < character.skeleton.size(); ++i) {
    const Eigen::Vector3d o = character.skeleton.rest_offsets[i] * s;
    joints.push_back({{"name", character.skeleton.names[i]},
                      {"parent", character.skeleton.parents[i]},
                      {"offset", {o.x(), o.y(), o.z()}}});
  }
  j["joints"] = joints;
  return j;
}

// Moves a take on the ground so the middle of its root path's bounding box is at the origin,
// the centre of the capture volume.
void center_on_volume(MotionClip& clip) {
  Eigen::Vector2d lo = clip.root.front().position, hi = lo;
  for (const RootState& r : clip.root) {
    lo = lo.cwiseMin(r.position);
    hi = hi.cwiseMax(r.position);
  }
  const Eigen::Vector2d shift = -0.5 * (lo + hi);
  for (RootState& r : clip.root) r.position += shift;
  for (Pose& p : clip.poses) p.root_position.head<2>() += shift;
}

// Refuse to overwrite a capture/ (or plates/) that synth did not make.
void prepare_output_dirs(const Session& session, bool plates) {
  fs::path capture = session.capture_dir();
  auto foreign = [](const fs::path& dir) {
    return fs::exists(dir) && !fs::is_empty(dir) && !fs::exists(dir / kSyntheticMarker);
  };
  if (foreign(capture) || (plates && foreign(session.dir("plates")))) {
    const fs::path which = foreign(capture) ? capture : session.dir("plates");
    throw InputError(fmt::format(
        "{} holds a capture that the synth stage did not make (no {} marker); refusing to "
        "overwrite it. Remove stages.synth from session.yaml to process a real capture.",
        which.string(), kSyntheticMarker));
  }
  // Plates of an earlier synthetic room must not survive into a screen studio's session.
  if (fs::exists(session.dir("plates") / kSyntheticMarker)) remove_folder(session.dir("plates"));
  // Stale takes of an earlier run must not survive into this one. Each folder goes as a whole
  // (a capture/ emptied half-way by a killed run would have lost its marker, and the rerun
  // would refuse it as a real capture).
  for (const fs::path& dir : {capture, session.ground_truth_dir(), session.calibration_dir()}) {
    remove_folder(dir);
    ensure_directory(dir);
  }
  write_file_atomic(capture / kSyntheticMarker, "made by fourd-synth\n");
  if (plates) {
    ensure_directory(session.dir("plates"));
    write_file_atomic(session.dir("plates") / kSyntheticMarker, "made by fourd-synth\n");
  }
}

}  // namespace

void SynthOptions::check() const {
  if (takes.empty()) throw ConfigError("takes: at least one take is needed");
  std::set<std::string> names;
  for (const MotionSpec& spec : takes) {
    if (!names.insert(spec.take).second) {
      throw ConfigError(fmt::format("takes: take '{}' appears twice", spec.take));
    }
  }
}

void run_synth(const Session& session, const StageArgs& args) {
  SynthOptions options;
  session.stage_options("synth", options);
  const double fps = session.config().fps;

  log::Timer timer;
  Character character = make_procedural_character(options.character, options.seed,
                                                  studio_key_color(options.studio));
  const Mesh surface = rest_surface(character);
  const double s = options.scale;
  log::info("performer{}: {} vertices, {} triangles, {} joints, height {:.3g} m{}{} ({:.1f} s)",
            options.character.body == "human" ? "" : " (" + options.character.body + ")",
            surface.num_vertices(), surface.num_triangles(), character.skeleton.size(),
            character.height * s, character.garment ? ", wearing a skirt" : "",
            s == 1 ? std::string() : fmt::format(" (the scene at scale {:g})", s), timer.seconds());

  // Every take is generated before anything is written: a take that cannot be performed
  // (too few frames for its jump, say) must not leave half a session behind.
  std::vector<MotionClip> clips;
  for (const MotionSpec& spec : options.takes) {
    clips.push_back(generate_motion(character.skeleton, spec, fps));
    if (!options.center_takes) continue;
    if (spec.start_position[0] != 0 || spec.start_position[1] != 0) {
      log::warn("take {}: start_position ({}, {}) is not used: every take's ground path is "
                "centred on the capture volume (center_takes, docs/synth.md \"Advanced\")",
                spec.take, spec.start_position[0], spec.start_position[1]);
    }
    center_on_volume(clips.back());
  }
  std::vector<Camera> rig = make_rig(options.rig);
  {
    // Per frame and camera an 8-bit RGB capture and a silhouette, uncompressed (the PNGs are
    // smaller; the noisy captures not by much), per frame a ground-truth mesh.
    std::uintmax_t frames = 0;
    for (const MotionClip& clip : clips) frames += clip.poses.size();
    std::uintmax_t pixels = 0;
    for (const Camera& cam : rig) {
      pixels += static_cast<std::uintmax_t>(cam.intrinsics.width) * cam.intrinsics.height;
    }
    const std::uintmax_t mesh_bytes = 12 * surface.num_vertices() + 13 * surface.num_triangles() + 512;
    require_free_space(session.root(), frames * (4 * pixels + mesh_bytes),
                       fmt::format("synth's {} frames of {} cameras", frames, rig.size()));
  }
  prepare_output_dirs(session, options.studio.room());

  // Calibration as the studio would deliver it, and the truth for validation.
  write_colmap_model(
      session.calibration_dir(),
      scaled_cameras(perturb_calibration(rig, options.calibration_noise, options.seed), s));
  const fs::path gt = session.ground_truth_dir();
  write_colmap_model(gt / "calibration", scaled_cameras(rig, s));
  write_mesh(gt / "template.ply", s == 1 ? surface : scaled_mesh(surface, s));
  write_image_atomic(gt / "texture.png", character.texture);
  write_json(gt / "character.json", character_json(character, surface, s));
  {
    YAML::Node used = to_yaml(options);
    if (options.character.garment == "none") {
      for (const char* key : CharacterOptions::kGarmentKeys) used["character"].remove(key);
    }
    if (options.character.body == "human") {
      for (const char* key : CharacterOptions::kBodyKeys) used["character"].remove(key);
    }
    for (std::size_t i = 0; i < options.takes.size(); ++i) {
      if (options.takes[i].pauses.empty()) used["takes"][i].remove("pauses");
    }
    YAML::Emitter out;
    out << used;
    write_file_atomic(gt / "synth_options.yaml", std::string(out.c_str()) + "\n");
  }

  StudioRenderer renderer(options.studio);
  if (options.studio.room()) {
    tbb::parallel_for(std::size_t{0}, rig.size(), [&](std::size_t c) {
      for (int i = 0; i < kPlates; ++i) {
        const RenderedView view =
            renderer.render(rig[c], mix_seed(options.seed, "plate", static_cast<int>(c), i));
        write_image_atomic(session.dir("plates") / rig[c].name / (frame_name(i) + ".png"),
                           view.image);
      }
    });
    log::info("wrote {} plates of the empty room per camera to {}", kPlates,
              session.dir("plates").string());
  }
  std::size_t total_frames = 0;
  for (const MotionSpec& spec : options.takes) total_frames += static_cast<std::size_t>(spec.frames);
  log::Progress progress("rendering", total_frames);
  for (const MotionClip& clip : clips) {
    const MotionSpec& spec = clip.spec;
    const int frames = static_cast<int>(clip.poses.size());
    PerformerSurface performer(character, clip.fps);
    for (int f = 0; f < frames; ++f) {
      Mesh posed = performer.next(clip.poses[f]);
      const std::string name = frame_name(f);
      Mesh gt_mesh;
      gt_mesh.positions = posed.positions;
      gt_mesh.triangles = posed.triangles;
      if (s != 1) gt_mesh = scaled_mesh(std::move(gt_mesh), s);
      write_mesh(gt / "meshes" / spec.take / (name + ".ply"), gt_mesh);
      renderer.set_performer(posed, character.texture);
      float gain = 1.0f;
      if (options.studio.room()) {
        const std::uint64_t h = mix_seed(options.seed, "flicker|" + spec.take, f);
        gain = static_cast<float>(1.0 + kFlicker * (2.0 * (h >> 11) * 0x1.0p-53 - 1.0));
      }
      tbb::parallel_for(std::size_t{0}, rig.size(), [&](std::size_t c) {
        const Camera& cam = rig[c];
        RenderedView view =
            renderer.render(cam, mix_seed(options.seed, spec.take, static_cast<int>(c), f), gain);
        write_image_atomic(session.capture_image(spec.take, cam.name, f), view.image);
        write_image_atomic(gt / "silhouettes" / spec.take / cam.name / (name + ".png"),
                           view.silhouette);
      });
      progress.step();
    }
    write_json(gt / "takes" / (spec.take + ".json"), take_json(clip, s));
    std::string params;
    for (const auto& [k, v] : clip.parameters) params += fmt::format(" {}={:.3f}", k, v);
    log::info("take {}: {} frames ({}){}", spec.take, frames, spec.kind, params);
  }
  log::info("wrote {} takes x {} cameras to {}", options.takes.size(), rig.size(),
            session.capture_dir().string());
}

}  // namespace fourd::synth
