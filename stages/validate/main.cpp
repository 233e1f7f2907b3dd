// fourd-validate: compares the stages' outputs with the ground truth; writes reports/.
// With --prepare-oracle it writes the oracle inputs (oracle/) from the ground truth instead.
#include "pipeline/core/log.h"
#include "stages/common/stage.h"
#include "stages/validate/oracle_inputs.h"
#include "stages/validate/validate.h"

int main(int argc, char** argv) {
  using namespace fourd;
  StageInfo info{"validate",
                 "Compares every stage's outputs with the ground truth of a synthetic session and "
                 "writes reports/metrics.json and reports/report.md (with pictures). Stages whose "
                 "outputs are absent are skipped. With --prepare-oracle, writes oracle/ instead: "
                 "stage inputs derived from the ground truth (options: stages.oracle).",
                 false, false,
                 {options_section<validate::ValidateOptions>("validate"),
                  options_section<validate::OracleOptions>("oracle")}};
  bool prepare_oracle = false;
  return run_stage_main(
      argc, argv, info,
      [&](CLI::App& app) {
        app.add_flag("--prepare-oracle", prepare_oracle,
                     "write oracle/ (segment, reconstruct, align inputs from ground truth) and "
                     "stop");
      },
      [&](const Session& session, const StageArgs&) {
        if (prepare_oracle) {
          validate::OracleOptions options;
          session.stage_options("oracle", options);
          validate::prepare_oracle_inputs(session, options);
          return;
        }
        validate::ValidateOptions options;
        session.stage_options("validate", options);
        for (const auto& r : validate::run_validation(session, options)) {
          if (!r.present) {
            log::info("{}: {}", r.stage, r.summary);
            continue;
          }
          for (const auto& m : r.metrics) {
            log::info("{} = {:.6g}", validate::metric_key(r.stage, m), m.value);
          }
        }
        log::info("wrote {}", (session.reports_dir() / "metrics.json").string());
      });
}
