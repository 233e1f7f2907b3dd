#include "pipeline/core/subject.h"

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>

#include "pipeline/core/config.h"
#include "pipeline/core/error.h"
#include "pipeline/core/files.h"
#include "pipeline/core/log.h"
#include "pipeline/core/session.h"
#include "pipeline/core/statistics.h"

namespace fs = std::filesystem;

namespace fourd {

double subject_scale_factor(double size, int steps_per_decade) {
  const double f = size / kReferenceSubjectSize;
  if (steps_per_decade <= 0) return f;
  const double k = std::round(steps_per_decade * std::log10(f));
  return k == 0 ? 1.0 : std::pow(10.0, k / steps_per_decade);
}

std::optional<Subject> read_subject(const fs::path& dir) {
  const fs::path file = dir / kSubjectFile;
  if (!fs::exists(file)) return std::nullopt;
  Subject s;
  try {
    const nlohmann::json j = nlohmann::json::parse(read_file(file));
    s.size = j.at("subject_size_m").get<double>();
    s.height = j.at("subject_height_m").get<double>();
    s.factor = j.at("scale_factor").get<double>();
  } catch (const nlohmann::json::exception& e) {
    throw InputError(fmt::format("{}: not a subject record: {}", file.string(), e.what()));
  }
  if (!(s.size > 0) || !(s.factor > 0) || !std::isfinite(s.size) || !std::isfinite(s.factor)) {
    throw InputError(fmt::format("{}: subject size {} m, scale factor {}: not positive",
                                 file.string(), s.size, s.factor));
  }
  // Named relative to the session (not its location), so that options.yaml is the same
  // wherever the session lies.
  s.source = (dir.filename() / kSubjectFile).generic_string();
  return s;
}

Subject measure_subject(const std::vector<Mesh>& meshes, const std::string& what) {
  std::vector<double> sizes, heights;
  for (const Mesh& m : meshes) {
    if (m.positions.empty()) continue;
    Vec3f lo, hi;
    bounding_box(m, &lo, &hi);
    const Vec3f side = hi - lo;
    sizes.push_back(side.maxCoeff());
    heights.push_back(side.z());
  }
  if (sizes.empty()) {
    throw InputError(fmt::format("{}: the subject's size cannot be measured: no mesh has a vertex",
                                 what));
  }
  Subject s;
  s.size = median(sizes);
  s.height = median(heights);
  s.factor = subject_scale_factor(s.size);
  s.source = fmt::format("measured on {} mesh(es) of {}", sizes.size(),
                         std::filesystem::path(what).filename().string());
  return s;
}

Subject stage_subject(const Session& session, const fs::path& input_dir,
                      const std::function<Subject()>& measure) {
  if (auto s = read_subject(input_dir)) return *s;
  if (auto s = read_subject(session.dir("reconstruct"))) return *s;
  return measure();
}

void log_subject(const std::string& stage, const Subject& subject, std::size_t scaled) {
  log::info("{}: subject {:.3g} m largest extent, {:.3g} m high ({}); scale factor {:.4g} of the "
            "{} m reference: {} length(s) not set are scaled by it",
            stage, subject.size, subject.height, subject.source, subject.factor,
            kReferenceSubjectSize, scaled);
}

std::string subject_comment(const Subject& subject, std::size_t scaled) {
  return fmt::format("# subject {:.4g} m (largest extent; height {:.4g} m; {}), scale factor "
                     "{:.4g} (reference {} m): {} length(s) not set in session.yaml or a preset "
                     "scaled by it\n",
                     subject.size, subject.height, subject.source, subject.factor,
                     kReferenceSubjectSize, scaled);
}

std::vector<std::size_t> spread_indices(std::size_t n, std::size_t count) {
  std::vector<std::size_t> out;
  const std::size_t k = std::min(n, count);
  for (std::size_t i = 0; i < k; ++i) out.push_back((2 * i + 1) * n / (2 * k));
  return out;
}

}  // namespace fourd
