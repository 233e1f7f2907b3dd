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

Session Session::open(const std::filesystem::path& root) {
  if (!std::filesystem::is_directory(root)) {
    throw InputError(fmt::format("{}: session folder does not exist", root.string()));
  }
  Session s;
  s.root_ = root;
  YAML::Node node = load_yaml_file(s.config_path());
  read_options(s.config_path().string(), node, "", s.config_);
  return s;
}

std::filesystem::path Session::capture_image(const std::string& take, const std::string& camera,
                                             int frame) const {
  return capture_dir() / take / camera / (frame_name(frame) + ".png");
}

std::string frame_name(int frame) { return fmt::format("{:06d}", frame); }

}  // namespace fourd
