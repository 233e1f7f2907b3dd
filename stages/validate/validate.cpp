#include "stages/validate/validate.h"

#include <fmt/format.h>

#include <cmath>
#include <exception>
#include <tuple>

#include "pipeline/core/error.h"
#include "pipeline/core/files.h"
#include "pipeline/core/log.h"

namespace fourd::validate {
namespace {

const char* input_name(InputKind kind) {
  switch (kind) {
    case InputKind::kPipeline:
      return "pipeline";
    case InputKind::kOracle:
      return "oracle";
    case InputKind::kNone:
      return "";
  }
  return "";
}

// Counts stay integers in the JSON; everything else is a double.
nlohmann::json metric_value(double v) {
  if (std::isfinite(v) && v == std::floor(v) && std::fabs(v) < 9.0e15) {
    return static_cast<std::int64_t>(v);
  }
  return v;
}

std::string format_value(double v) {
  if (std::isfinite(v) && v == std::floor(v) && std::fabs(v) < 9.0e15) {
    return fmt::format("{}", static_cast<std::int64_t>(v));
  }
  return fmt::format("{:.6g}", v);
}

std::string report_markdown(const Session& session, const std::vector<StageReport>& reports) {
  std::string md = fmt::format("# Validation report: {}\n\n", session.config().name);
  md += fmt::format(
      "Written by fourd-validate on {}. Machine-readable numbers: [metrics.json](metrics.json), "
      "keys `<stage>.<metric>` or `<stage>.<input>.<metric>` where `<input>` says whether the "
      "stage ran on the previous stage's output (`pipeline`) or on ground truth (`oracle`).\n\n",
      log::local_time());
  for (const auto& r : reports) {
    md += fmt::format("## {}\n\n", r.stage);
    if (!r.error.empty()) {
      md += fmt::format("**Validation failed:** {}\n\n", r.error);
      continue;
    }
    md += r.summary + "\n\n";
    if (!r.present) continue;
    if (!r.metrics.empty()) {
      md += "| metric | value | inputs | meaning |\n|---|---:|---|---|\n";
      for (const auto& m : r.metrics) {
        const char* input = input_name(m.input);
        md += fmt::format("| `{}` | {} | {} | {} |\n", metric_key(r.stage, m),
                          format_value(m.value), *input ? input : "-", m.meaning);
      }
      md += "\n";
    }
    if (!r.details.empty()) md += r.details + "\n\n";
    for (const auto& p : r.pictures) {
      md += fmt::format("![{}]({})\n\n*{}*\n\n", p.caption, p.file, p.caption);
    }
  }
  return md;
}

}  // namespace

std::vector<RunFolder> run_folders(const Session& session, const std::string& stage,
                                   const std::string& marker) {
  std::vector<RunFolder> out;
  for (const auto& [suffix, input, label] :
       {std::tuple{"", InputKind::kPipeline, "pipeline"},
        std::tuple{"_oracle", InputKind::kOracle, "oracle"}}) {
    std::filesystem::path dir = session.dir(stage + suffix);
    std::error_code ec;
    if (std::filesystem::exists(dir / marker, ec)) out.push_back({dir, input, label});
  }
  return out;
}

nlohmann::json read_json(const std::filesystem::path& path) {
  try {
    return nlohmann::json::parse(read_file(path));
  } catch (const nlohmann::json::exception& e) {
    throw InputError(fmt::format("{}: not valid JSON: {}", path.string(), e.what()));
  }
}

const std::vector<ValidatorEntry>& validators() {
  static const std::vector<ValidatorEntry> list = {
      {"synth", validate_synth},
      {"segment", validate_segment},
      {"reconstruct", validate_reconstruct},
      {"align", validate_align},
      {"timewarp", validate_timewarp},
      {"blend", validate_blend},
      {"transitions", validate_transitions},
      {"graph", validate_graph},
      {"paths", validate_paths},
      {"texture", validate_texture},
  };
  return list;
}

std::string metric_key(const std::string& stage, const Metric& metric) {
  const char* input = input_name(metric.input);
  return *input ? fmt::format("{}.{}.{}", stage, input, metric.name)
                : fmt::format("{}.{}", stage, metric.name);
}

nlohmann::json metrics_json(const std::vector<StageReport>& reports) {
  nlohmann::json doc = nlohmann::json::object();
  for (const auto& r : reports) {
    if (!r.present || !r.error.empty() || r.metrics.empty()) continue;
    nlohmann::json& stage = doc[r.stage];
    for (const auto& m : r.metrics) {
      const char* input = input_name(m.input);
      if (*input) {
        stage[input][m.name] = metric_value(m.value);
      } else {
        stage[m.name] = metric_value(m.value);
      }
    }
  }
  return doc;
}

std::vector<StageReport> run_validation(const Session& session, const ValidateOptions& options) {
  std::filesystem::path reports_dir = session.reports_dir();
  ensure_directory(reports_dir);
  ValidationContext context{session, options, reports_dir};
  std::vector<StageReport> reports;
  std::exception_ptr first_error;
  for (const auto& v : validators()) {
    try {
      reports.push_back(v.run(context));
      reports.back().stage = v.stage;
    } catch (const std::exception& e) {
      // Keep validating the other stages; the error is rethrown once the reports are written.
      if (!first_error) first_error = std::current_exception();
      StageReport failed;
      failed.stage = v.stage;
      failed.error = e.what();
      reports.push_back(std::move(failed));
    }
  }
  write_file_atomic(reports_dir / "metrics.json", metrics_json(reports).dump(2) + "\n");
  write_file_atomic(reports_dir / "report.md", report_markdown(session, reports));
  if (first_error) std::rethrow_exception(first_error);
  return reports;
}

}  // namespace fourd::validate
