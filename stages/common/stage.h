#pragma once
// The thin main() every stage executable shares: common command-line options, the stage log
// under logs/, timing, and one place that turns typed errors into messages and exit codes.
#include <CLI/CLI.hpp>

#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "pipeline/core/frame_selection.h"
#include "pipeline/core/session.h"

namespace fourd {

struct StageArgs {
  std::string session_dir;
  // Validation mode (docs/design.md "Oracle inputs"): read inputs derived from ground truth (see
  // stage_input_dir) instead of the previous stage's outputs, and write to <stage>_oracle/ so
  // pipeline and oracle results coexist.
  bool oracle = false;
  FrameSelection selection;  // --take/--frames; checked against the capture by the stage
  // --finish: the last job of a stage split into frame-range jobs: no frame is processed; the
  // stage checks that every frame's output exists and writes its reports from them.
  bool finish = false;
  // Stages split along a tree of frames (StageInfo::tree_jobs: align): --tree builds the tree
  // and the plan of `branches` branch jobs; --branch K registers branch K; --finish merges.
  bool tree = false;
  int branches = 1;
  int branch = -1;
  int threads = 0;     // 0: all cores
  bool verbose = false;
};

// One section of session.yaml a stage reads (stages.<name>): its defaults as YAML and as the
// help text of --help. Made from the options struct by options_section<T>(name).
struct OptionsSection {
  std::string name;       // "reconstruct" -> stages.reconstruct
  std::string help;       // describe_options(T{})
  YAML::Node defaults;    // to_yaml(T{})
};

// `node` with every non-integer number in its shortest round-trip form (0.1, not
// 0.10000000000000001 as YAML's emitter writes doubles), for YAML meant to be read by people.
YAML::Node shortest_numbers(const YAML::Node& node);

template <class T>
OptionsSection options_section(std::string name) {
  // GCC 12 at -O3 takes a default-constructed options struct's strings for uninitialised
  // (-Wmaybe-uninitialized, a known false positive with inlined std::string destructors).
#if defined(__GNUC__) && !defined(__clang__)
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wmaybe-uninitialized"
#endif
  const T defaults{};
  return {std::move(name), describe_options(defaults), shortest_numbers(to_yaml(defaults))};
#if defined(__GNUC__) && !defined(__clang__)
#pragma GCC diagnostic pop
#endif
}

struct StageInfo {
  const char* name;         // "synth"
  const char* description;  // one paragraph for --help
  bool takes_frame_range = false;
  bool supports_oracle = false;
  // The sections of session.yaml the stage reads, shown at the end of --help and printed as
  // YAML by --print-defaults (what `fourd defaults` gathers into config/defaults.yaml).
  std::vector<OptionsSection> options;
  // Accepts --finish (a per-frame stage split into jobs by the driver or a workflow).
  bool has_finish_job = false;
  // Runs as a tree job, branch jobs and a finish job (--tree/--branches, --branch, --finish).
  bool tree_jobs = false;
};

// The job part a tree-split stage's job names its log after: "tree", "branch<K>", or "" (the
// finish job, or a stage run whole).
std::string tree_job_part(const StageArgs& args);

// Folder a stage reads the outputs of `input_stage` from: <session>/<input_stage>; in oracle
// mode <session>/oracle/<input_stage> (made from ground truth by `fourd-validate
// --prepare-oracle`) when ground truth stands in for that stage (kPreparedOracleInputs), else
// <session>/<input_stage>_oracle when the input stage ran on oracle inputs too.
std::filesystem::path stage_input_dir(const Session& session, const StageArgs& args,
                                      const std::string& input_stage);
// Folder a stage writes to: <session>/<stage>, or <session>/<stage>_oracle in oracle mode.
std::filesystem::path stage_output_dir(const Session& session, const StageArgs& args,
                                       const std::string& stage);

// Parses the common options plus those `add_options` registers, opens the job's log
// (logs/<job_log_name>) in the session, runs `body`, and returns the process exit code. Never
// throws.
int run_stage_main(int argc, char** argv, const StageInfo& info,
                   const std::function<void(CLI::App&)>& add_options,
                   const std::function<void(const Session&, const StageArgs&)>& body);

}  // namespace fourd
