#include "stages/common/stage.h"

#include <tbb/global_control.h>

#include <charconv>
#include <cstdio>
#include <memory>

#include "pipeline/core/command_line.h"
#include "pipeline/core/error.h"
#include "pipeline/core/guarded.h"
#include "pipeline/core/log.h"

namespace fourd {

YAML::Node shortest_numbers(const YAML::Node& node) {
  if (node.IsMap()) {
    YAML::Node out(YAML::NodeType::Map);
    for (const auto& kv : node) out[kv.first.as<std::string>()] = shortest_numbers(kv.second);
    return out;
  }
  if (node.IsSequence()) {
    YAML::Node out(YAML::NodeType::Sequence);
    for (const auto& item : node) out.push_back(shortest_numbers(item));
    return out;
  }
  if (!node.IsScalar()) return node;
  const std::string& text = node.Scalar();
  if (text.find_first_of(".eE") == std::string::npos) return node;  // integers, words
  double value = 0;
  const auto [end, ec] = std::from_chars(text.data(), text.data() + text.size(), value);
  if (ec != std::errc() || end != text.data() + text.size()) return node;
  return YAML::Node(fmt::format("{}", value));
}

std::filesystem::path stage_input_dir(const Session& session, const StageArgs& args,
                                      const std::string& input_stage) {
  if (!args.oracle) return session.dir(input_stage);
  // Ground truth itself where it can stand in for the input (the stage inherits no error);
  // else the oracle run of the input stage when there is one, else its copy under oracle/
  // (the same rule as the driver's with_oracle_variants()).
  if (is_prepared_oracle_input(input_stage)) return session.dir("oracle") / input_stage;
  std::filesystem::path chained = session.dir(input_stage + "_oracle");
  std::error_code ec;
  if (std::filesystem::is_directory(chained, ec)) return chained;
  return session.dir("oracle") / input_stage;
}

std::filesystem::path stage_output_dir(const Session& session, const StageArgs& args,
                                       const std::string& stage) {
  return session.dir(args.oracle ? stage + "_oracle" : stage);
}

std::string tree_job_part(const StageArgs& args) {
  if (args.tree) return "tree";
  if (args.branch >= 0) return "branch" + std::to_string(args.branch);
  return {};
}

int run_stage_main(int argc, char** argv, const StageInfo& info,
                   const std::function<void(CLI::App&)>& add_options,
                   const std::function<void(const Session&, const StageArgs&)>& body) {
  CLI::App app{info.description, std::string("fourd-") + info.name};
  StageArgs args;
  std::string take, frames;
  app.add_option("session", args.session_dir, "session folder (holds session.yaml)")->required();
  app.add_option("--threads", args.threads, "worker threads (0 = all cores)")->check(CLI::NonNegativeNumber);
  app.add_flag("-v,--verbose", args.verbose, "debug messages");
  if (info.takes_frame_range) {
    app.add_option("--take", take, "process only this take");
    app.add_option("--frames", frames,
                   "process only frames FIRST:LAST (inclusive; comma-separated ranges, which must "
                   "not overlap)");
  }
  if (info.tree_jobs) {
    app.add_flag("--tree", args.tree,
                 "the first job: build the tree over all frames and plan --branches branch jobs");
    app.add_option("--branches", args.branches, "branch jobs the --tree job plans")
        ->check(CLI::Range(1, 100000));
    app.add_option("--branch", args.branch,
                   "register the frames of branch job K (0-based) of the plan the --tree job wrote")
        ->check(CLI::NonNegativeNumber);
  }
  if (info.has_finish_job || info.tree_jobs) {
    app.add_flag("--finish", args.finish,
                 "after jobs that each did a --take/--frames range: process no frame, check "
                 "that every frame's output exists and write the stage's reports");
  }
  if (info.supports_oracle) {
    app.add_flag("--oracle", args.oracle,
                 "validation only: read inputs derived from ground truth (oracle/) instead of the "
                 "previous stage's, and write to <stage>_oracle/");
  }
  if (add_options) add_options(app);
  if (!info.options.empty()) {
    // A callback that ends the parse (as --help does), so no session argument is needed.
    app.add_flag_callback(
        "--print-defaults",
        [&info] {
          YAML::Node stages(YAML::NodeType::Map);
          for (const auto& section : info.options) stages[section.name] = YAML::Clone(section.defaults);
          YAML::Emitter out;
          out << stages;
          std::fputs(out.c_str(), stdout);
          std::fputc('\n', stdout);
          throw CLI::Success();
        },
        "print the stage's session.yaml sections with their defaults (YAML) and exit");
    std::string footer;
    for (const auto& section : info.options) {
      footer += fmt::format("\nOptions in session.yaml, section stages.{} (name = default: "
                            "meaning):\n{}",
                            section.name, section.help);
    }
    app.footer(footer);
  }
  if (const auto code = parse_command_line(app, argc, argv)) return *code;
  if (args.verbose) log::set_level(log::Level::kDebug);
  std::unique_ptr<tbb::global_control> threads;
  if (args.threads > 0) {
    threads = std::make_unique<tbb::global_control>(tbb::global_control::max_allowed_parallelism,
                                                    args.threads);
  }
  const int code = run_guarded(fmt::format("fourd-{}", info.name), [&]() -> int {
    args.selection = parse_frame_selection(take, frames);
    if (args.finish && !args.selection.whole()) {
      throw UsageError("--finish processes no frame: it takes no --take/--frames");
    }
    if (int(args.tree) + int(args.branch >= 0) + int(args.finish) > 1) {
      throw UsageError("--tree, --branch and --finish are different jobs: give one of them");
    }
    if (args.branch >= 0 && !args.selection.whole()) {
      throw UsageError("--branch takes its frames from the plan: no --take/--frames");
    }
    Session session = Session::open(args.session_dir);
    log::open_file(session.logs_dir() /
                   job_log_name(std::string(info.name) + (args.oracle ? "_oracle" : ""),
                                args.selection, tree_job_part(args)));
    log::info("fourd-{} on {}", info.name, session.root().string());
    log::Timer timer;
    body(session, args);
    log::info("fourd-{} finished in {:.1f} s ({} warnings)", info.name, timer.seconds(),
              log::warning_count());
    return kExitOk;
  });
  log::open_file({});  // after the error, if any, is logged there
  return code;
}

}  // namespace fourd
