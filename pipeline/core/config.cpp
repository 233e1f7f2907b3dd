#include "pipeline/core/config.h"

namespace fourd {
namespace config_detail {

std::string location(const std::string& file, const YAML::Node& node) {
  YAML::Mark mark = node.Mark();
  if (mark.is_null()) return file;
  return fmt::format("{}:{}:{}", file, mark.line + 1, mark.column + 1);
}

void fail(const std::string& file, const YAML::Node& node, const std::string& path,
          const std::string& message) {
  throw ConfigError(fmt::format("{}: {}: {}", location(file, node), path, message));
}

}  // namespace config_detail

YAML::Node load_yaml_file(const std::filesystem::path& path) {
  if (!std::filesystem::exists(path)) {
    throw ConfigError(fmt::format("{}: config file does not exist", path.string()));
  }
  try {
    return YAML::LoadFile(path.string());
  } catch (const YAML::ParserException& e) {
    throw ConfigError(fmt::format("{}:{}:{}: YAML syntax error: {}", path.string(),
                                  e.mark.line + 1, e.mark.column + 1, e.msg));
  } catch (const YAML::BadFile&) {
    throw IoError(fmt::format("{}: cannot read config file", path.string()));
  }
}

}  // namespace fourd
