#include "pipeline/core/session.h"

#include <set>

#include "pipeline/core/error.h"

namespace fourd {

void MotionClassConfig::check() const {
  if (name.empty()) throw ConfigError("a motion class has no name");
  if (takes.empty()) throw ConfigError(fmt::format("motion class '{}' lists no takes", name));
}

void SessionConfig::check() const {
  std::set<std::string> classes;
  for (const auto& m : motions) {
    if (!classes.insert(m.name).second) {
      throw ConfigError(fmt::format("motion class '{}' is declared twice", m.name));
    }
    std::set<std::string> takes(m.takes.begin(), m.takes.end());
    if (takes.size() != m.takes.size()) {
      throw ConfigError(fmt::format("motion class '{}' lists a take twice", m.name));
    }
  }
  for (const auto& t : transitions) {
    for (const auto* end : {&t.from, &t.to}) {
      if (!classes.count(*end)) {
        throw ConfigError(fmt::format("transition {} -> {} names unknown motion class '{}'",
                                      t.from, t.to, *end));
      }
    }
  }
  if (stages && !stages.IsNull() && !stages.IsMap()) throw ConfigError("stages: expected a mapping of stage names");
}

namespace {

YAML::Node section_or_empty(const YAML::Node& node) {
  if (node.IsDefined() && node.IsMap()) return node;
  return YAML::Node(YAML::NodeType::Map);
}

// A preset file: one `stages:` mapping of stage names, nothing else.
YAML::Node read_preset(const std::filesystem::path& file) {
  YAML::Node node = load_yaml_file(file);
  if (node.IsNull()) return YAML::Node(YAML::NodeType::Map);
  if (!node.IsMap()) {
    throw ConfigError(fmt::format("{}: a preset is a mapping with one key, stages", file.string()));
  }
  for (const auto& kv : node) {
    const std::string key = kv.first.as<std::string>();
    if (key != "stages") {
      throw ConfigError(fmt::format("{}:{}: unknown key '{}' in a preset (a preset holds only "
                                    "stages:)",
                                    file.string(), kv.first.Mark().line + 1, key));
    }
  }
  const YAML::Node stages = node["stages"];
  if (!stages.IsNull() && !stages.IsMap()) {
    throw ConfigError(fmt::format("{}: stages: expected a mapping of stage names", file.string()));
  }
  return section_or_empty(stages);
}

}  // namespace

Session Session::open(const std::filesystem::path& root) {
  if (!std::filesystem::is_directory(root)) {
    throw InputError(fmt::format("{}: session folder does not exist", root.string()));
  }
  Session s;
  s.root_ = root;
  YAML::Node node = load_yaml_file(s.config_path());
  read_options(s.config_path().string(), node, "", s.config_);
  for (const auto& name : s.config_.presets) {
    std::filesystem::path file = name;
    if (file.is_relative()) file = root / file;
    if (!std::filesystem::is_regular_file(file)) {
      throw ConfigError(fmt::format("{}: presets: '{}' does not exist ({})",
                                    s.config_path().string(), name, file.string()));
    }
    s.layers_.push_back({file, read_preset(file)});
  }
  s.layers_.push_back({s.config_path(), section_or_empty(s.config_.stages)});
  return s;
}

std::vector<YAML::Node> Session::stage_sections(const std::string& stage) const {
  std::vector<YAML::Node> out;
  for (const auto& layer : layers_) {
    YAML::Node section = layer.stages[stage];
    if (section.IsDefined() && !section.IsNull()) out.push_back(section);
  }
  return out;
}

bool Session::has_stage_section(const std::string& stage) const {
  return !stage_sections(stage).empty();
}

std::filesystem::path Session::capture_image(const std::string& take, const std::string& camera,
                                             int frame) const {
  return capture_dir() / take / camera / (frame_name(frame) + ".png");
}

std::string frame_name(int frame) { return fmt::format("{:06d}", frame); }

}  // namespace fourd
