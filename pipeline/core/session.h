#pragma once
// The session folder (see docs/design.md "The session folder") and its session.yaml.
#include <yaml-cpp/yaml.h>

#include <array>
#include <filesystem>
#include <string_view>
#include <string>
#include <vector>

#include "pipeline/core/config.h"

namespace fourd {

// A motion class: takes of one kind of motion that form one parametric motion space.
struct MotionClassConfig {
  std::string name;                 // e.g. "locomotion"
  std::vector<std::string> takes;   // takes blended in this space, in parameter order
  std::string parameter;            // high-level parameter: speed | direction | length | height | reach
  bool cyclic = false;              // walk/run/turn cycles loop; jumps and reaches do not

  template <class V>
  void visit(V& v) {
    v("name", name, "motion class name");
    v("takes", takes, "takes of this class, in parameter order");
    v("parameter", parameter, "high-level parameter (speed, direction, length, height, reach)");
    v("cyclic", cyclic, "whether the motion loops");
  }
  void check() const;
};

struct TransitionConfig {
  std::string from;
  std::string to;
  template <class V>
  void visit(V& v) {
    v("from", from, "source motion class");
    v("to", to, "target motion class");
  }
};

// Stage outputs that ground truth can stand for: `fourd-validate --prepare-oracle` derives
// oracle/<stage>/ for each of these from ground_truth/. An oracle run of a stage reads these
// from oracle/ (so it carries none of the errors of the stages before it), and any other input
// from the oracle run of the stage that writes it (motionspace_oracle reads timewarp_oracle).
inline constexpr std::array<std::string_view, 3> kPreparedOracleInputs = {
    "segment", "reconstruct", "align"};
inline bool is_prepared_oracle_input(std::string_view stage) {
  for (std::string_view s : kPreparedOracleInputs) {
    if (s == stage) return true;
  }
  return false;
}

// The record fourd-import writes last into every folder it fills (calibration/, capture/,
// plates/, masks/, reconstruct/, align/). The driver never runs a stage whose folder holds one:
// what the user supplied is never overwritten.
inline constexpr const char* kImportRecordFile = "imported.json";

struct SessionConfig {
  std::string name = "session";
  double fps = 25;  // capture frame rate [frames/s]
  std::vector<MotionClassConfig> motions;
  std::vector<TransitionConfig> transitions;
  // Stages that also run on inputs derived from ground truth (synthetic sessions; docs/design.md,
  // "Oracle inputs"), so validation reports pipeline and oracle numbers side by side.
  std::vector<std::string> oracle;
  // Preset files (relative to the session folder, e.g. ../config/presets/preview.yaml), each
  // holding a `stages:` mapping, applied in order before this file's own stages section.
  std::vector<std::string> presets;
  // Per-stage sections, each mapped by its stage onto its own options struct.
  YAML::Node stages;

  template <class V>
  void visit(V& v) {
    v("name", name, "session name");
    v("fps", fps, "capture frame rate [frames/s]", Range{1, 1000});
    v("motions", motions, "motion classes (parametric motion spaces)");
    v("transitions", transitions, "transitions the motion graph allows");
    v("oracle", oracle, "stages that also run on ground-truth-derived inputs (validation)");
    v("presets", presets, "files of stage options applied before stages:, in order");
    v("stages", stages, "per-stage options");
  }
  void check() const;  // unique names; transitions name known classes
};

class Session {
 public:
  // Opens an existing session folder and reads its session.yaml. Throws InputError if the
  // folder does not exist, ConfigError if session.yaml is missing or invalid.
  static Session open(const std::filesystem::path& root);

  const std::filesystem::path& root() const { return root_; }
  const SessionConfig& config() const { return config_; }
  std::filesystem::path config_path() const { return root_ / "session.yaml"; }

  // Maps stages.<stage> onto `opts`: the defaults, then each preset's section, then
  // session.yaml's; errors name the file and line the value came from. With `set_keys`, the
  // keys any of them set ("stages.<stage>.<key>...") are added to it (scale_unset_lengths).
  template <class T>
  void stage_options(const std::string& stage, T& opts, SetKeys* set_keys = nullptr) const {
    for (const auto& layer : layers_) {
      read_options(layer.file.string(), layer.stages[stage], "stages." + stage, opts, set_keys);
    }
  }
  // The stages.<stage> sections that apply, in the order they are applied (presets first);
  // what the driver hashes to tell whether a stage's options changed.
  std::vector<YAML::Node> stage_sections(const std::string& stage) const;
  // Whether any layer has a stages.<stage> section.
  bool has_stage_section(const std::string& stage) const;

  std::filesystem::path dir(const std::string& sub) const { return root_ / sub; }
  std::filesystem::path calibration_dir() const { return root_ / "calibration"; }
  std::filesystem::path capture_dir() const { return root_ / "capture"; }
  std::filesystem::path ground_truth_dir() const { return root_ / "ground_truth"; }
  std::filesystem::path reports_dir() const { return root_ / "reports"; }
  std::filesystem::path logs_dir() const { return root_ / "logs"; }
  // capture/<take>/<camera>/<frame 000000>.png
  std::filesystem::path capture_image(const std::string& take, const std::string& camera,
                                      int frame) const;

 private:
  struct Layer {
    std::filesystem::path file;  // the preset file or session.yaml
    YAML::Node stages;           // its stages: mapping (empty map when absent)
  };
  std::filesystem::path root_;
  SessionConfig config_;
  std::vector<Layer> layers_;
};

// "000042": how every per-frame file is named.
std::string frame_name(int frame);

}  // namespace fourd
