// `fourd`: runs the pipeline's stage executables over a session folder (see driver.h).
#include <fmt/format.h>
#include <tbb/global_control.h>

#include <CLI/CLI.hpp>
#include <unistd.h>

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <memory>

#include "pipeline/core/command_line.h"
#include "pipeline/core/guarded.h"
#include "pipeline/core/log.h"
#include "pipeline/driver/driver.h"
#include "pipeline/driver/workflow.h"

namespace {

using namespace fourd;
using namespace fourd::driver;

std::string human_bytes(std::uint64_t bytes) {
  if (bytes >= (1ull << 30)) return fmt::format("{:.1f} GB", bytes / double(1ull << 30));
  if (bytes >= (1ull << 20)) return fmt::format("{:.1f} MB", bytes / double(1ull << 20));
  if (bytes >= (1ull << 10)) return fmt::format("{:.1f} kB", bytes / double(1ull << 10));
  return fmt::format("{} B", bytes);
}

std::string stage_list(const std::vector<StageSpec>& stages) {
  std::string out;
  for (const auto& s : stages) out += (out.empty() ? "" : ", ") + s.name;
  return out.empty() ? "none built" : out;
}

void print_event(const StageEvent& e) {
  switch (e.kind) {
    case StageEvent::Kind::kSkipped:
      log::info("[{}/{}] {}: up to date, skipped", e.index, e.count, e.stage);
      break;
    case StageEvent::Kind::kStarted:
      log::info("[{}/{}] {} ... ({})", e.index, e.count, e.stage, e.reason);
      break;
    case StageEvent::Kind::kFinished:
      log::info("[{}/{}] {} done in {:.1f} s{} (CPU {:.1f} s, peak memory {})", e.index, e.count,
                e.stage, e.seconds, e.jobs > 1 ? fmt::format(", {} jobs", e.jobs) : "",
                e.usage.cpu_seconds, human_bytes(e.usage.peak_rss_bytes));
      break;
    case StageEvent::Kind::kFailed:
      log::error("[{}/{}] {} failed after {:.1f} s ({})", e.index, e.count, e.stage, e.seconds,
                 e.reason);
      break;
  }
}

int command_run(const std::string& session_dir, const RunRequest& request,
                const std::vector<StageSpec>& built) {
  log::Timer timer;
  RunResult result = run_pipeline(session_dir, built, request, print_event);
  if (!result.failed_stage.empty()) {
    log::error("fourd: stopped: stage {} failed (exit code {}); its log is {}", result.failed_stage,
               result.exit_code, result.log_file.string());
    return result.exit_code;
  }
  log::info("fourd: ran {} stage(s), skipped {} up to date, in {:.1f} s", result.ran.size(),
            result.skipped.size(), timer.seconds());
  return kExitOk;
}

int command_status(const std::string& session_dir, const std::vector<StageSpec>& built) {
  std::vector<StageStatus> table = session_status(session_dir, built);
  fmt::print("{:<18} {:<21} {:<20} {:>9} {:>9} {:>10} {:>10}  {}\n", "stage", "state", "last run",
             "duration", "CPU", "peak mem", "outputs", "notes");
  for (const auto& s : table) {
    std::string when = s.record ? s.record->finished : "-";
    std::string took = s.record ? fmt::format("{:.1f} s", s.record->seconds) : "-";
    std::string cpu = s.record && s.record->cpu_seconds > 0
                          ? fmt::format("{:.1f} s", s.record->cpu_seconds) : "-";
    std::string peak = s.record && s.record->peak_rss_bytes > 0
                           ? human_bytes(s.record->peak_rss_bytes) : "-";
    fmt::print("{:<18} {:<21} {:<20} {:>9} {:>9} {:>10} {:>10}  {}\n", s.stage,
               state_name(s.state), when, took, cpu, peak,
               s.output_bytes ? human_bytes(s.output_bytes) : "-", s.detail);
  }
  return kExitOk;
}

// Replaces this process by fourd-import (beside fourd) with `arguments`.
int command_import(const std::vector<std::string>& arguments) {
  const fs::path exe = executable_dir() / "fourd-import";
  std::error_code ec;
  if (!fs::is_regular_file(exe, ec)) {
    throw UsageError(fmt::format("fourd-import is not built (no {})", exe.string()));
  }
  std::vector<std::string> args = {exe.string()};
  args.insert(args.end(), arguments.begin(), arguments.end());
  std::vector<char*> argv;
  for (auto& a : args) argv.push_back(a.data());
  argv.push_back(nullptr);
  std::fflush(stdout);
  std::fflush(stderr);
  ::execv(exe.c_str(), argv.data());
  throw IoError(fmt::format("cannot start {}: {}", exe.string(), std::strerror(errno)));
}

int command_digest(const std::string& session_dir, std::vector<std::string> folders) {
  const fs::path root(session_dir);
  if (!fs::is_directory(root)) throw InputError(fmt::format("{}: not a folder", session_dir));
  if (folders.empty()) {
    for (const auto& entry : fs::directory_iterator(root)) {
      const std::string name = entry.path().filename().string();
      if (entry.is_directory() && name != "logs") folders.push_back(name);
    }
  }
  for (const auto& [path, hash] : hash_folders(root, folders)) fmt::print("{}  {}\n", hash, path);
  return kExitOk;
}

}  // namespace

int main(int argc, char** argv) {
  std::vector<StageSpec> built;
  try {
    built = built_stages(executable_dir());
  } catch (const Error& e) {
    log::error("fourd: {}", e.what());
    return e.exit_code();
  }

  CLI::App app{
      "fourd: runs the 4D parametric motion graph pipeline over a session folder.\n"
      "Stages run in order as separate programs (fourd-<stage>, beside fourd); a stage whose\n"
      "inputs, options and program have not changed since its last successful run is skipped.",
      "fourd"};
  app.require_subcommand(1);
  app.footer("stages built, in order: " + stage_list(built));

  std::string session_dir;
  RunRequest request;
  std::vector<std::string> oracle;
  CLI::App* run =
      app.add_subcommand("run", "run the stages of a session, skipping up-to-date ones");
  run->add_option("session", session_dir, "session folder (holds session.yaml)")->required();
  CLI::Option* only = run->add_option("--only", request.only, "run only this stage");
  run->add_option("--from", request.from, "run this stage and every stage after it")
      ->excludes(only);
  run->add_flag("--force", request.force, "rerun the selected stages even when up to date");
  run->add_option("--oracle", oracle,
                  "also run STAGE on inputs derived from ground truth, writing STAGE_oracle/\n"
                  "beside its pipeline output (validation; repeatable; session.yaml 'oracle:'\n"
                  "lists stages that always get this run)")
      ->allow_extra_args(false)  // one stage per --oracle, so the session positional is not eaten
      ->type_name("STAGE");
  run->add_option("--threads", request.threads, "worker threads per stage (0 = all cores)")
      ->check(CLI::NonNegativeNumber);
  run->add_option("--frames-per-job", request.frames_per_job,
                  "per-frame stages (segment, reconstruct) run as jobs of at most N frames of one\n"
                  "take, then a --finish job (0 = one job per take)")
      ->check(CLI::NonNegativeNumber);
  run->add_option("--branch-jobs", request.branch_jobs,
                  "align runs as a tree job, N branch jobs (independent subtrees of its shape\n"
                  "tree) and a --finish job; the result does not depend on N")
      ->check(CLI::PositiveNumber);
  run->add_flag("-v,--verbose", request.verbose, "debug messages (also from the stages)");
  run->footer("stages built, in order: " + stage_list(built) +
              "\nEach stage logs to <session>/logs/<stage>.log. Without a stages.synth section in "
              "session.yaml,\ncapture/ is a real capture and synth is not run.");

  WorkflowRequest workflow_request;
  std::vector<std::string> workflow_oracle;
  CLI::App* workflow = app.add_subcommand(
      "workflow",
      "write a Snakemake workflow of the session's jobs to <session>/workflow/ (Snakefile,\n"
      "config.yaml, profiles/slurm/): `snakemake -s <session>/workflow/Snakefile --cores N`");
  workflow->add_option("session", session_dir, "session folder (holds session.yaml)")->required();
  workflow->add_option("--frames-per-job", workflow_request.frames_per_job,
                       "per-frame stages: frames of one take per job")
      ->check(CLI::PositiveNumber);
  workflow->add_option("--branch-jobs", workflow_request.branch_jobs,
                       "align: branch jobs (independent subtrees of its shape tree)")
      ->check(CLI::PositiveNumber);
  workflow->add_option("--oracle", workflow_oracle, "as for `fourd run`")
      ->allow_extra_args(false)
      ->type_name("STAGE");

  CLI::App* status = app.add_subcommand("status", "show the state of every stage of a session");
  status->add_option("session", session_dir, "session folder (holds session.yaml)")->required();

  std::vector<std::string> digest_folders;
  CLI::App* digest = app.add_subcommand(
      "digest",
      "print the content hash of every result file under the session's folders, the way the\n"
      "driver compares them: run records (times, CPU, job split, logs) left out, so two runs\n"
      "with the same results print the same lines");
  digest->add_option("session", session_dir, "session folder")->required();
  digest->add_option("folders", digest_folders,
                     "sub-folders to hash (default: every sub-folder but logs/)");

  CLI::App* defaults = app.add_subcommand(
      "defaults", "print every stage's session.yaml options with their defaults (YAML)");

  // `fourd import ...` is fourd-import (beside fourd) with the same arguments.
  CLI::App* import = app.add_subcommand(
      "import",
      "bring a studio's capture into a session: calibration, videos or image folders, plates,\n"
      "masks, meshes (runs fourd-import with the arguments that follow; fourd import --help)");
  import->prefix_command();
  import->set_help_flag();  // --help goes to fourd-import

  if (const auto code = parse_command_line(app, argc, argv)) return *code;
  if (request.verbose) log::set_level(log::Level::kDebug);
  // --threads also bounds the driver's own work (hashing inputs and outputs).
  std::unique_ptr<tbb::global_control> threads;
  if (request.threads > 0) {
    threads = std::make_unique<tbb::global_control>(tbb::global_control::max_allowed_parallelism,
                                                    request.threads);
  }
  request.oracle.insert(oracle.begin(), oracle.end());

  return run_guarded("fourd", [&]() -> int {
    if (*import) return command_import(import->remaining());
    if (*run) return command_run(session_dir, request, built);
    if (*workflow) {
      workflow_request.oracle.insert(workflow_oracle.begin(), workflow_oracle.end());
      WorkflowFiles files = write_workflow(session_dir, built, workflow_request);
      log::info("fourd: wrote {} ({} jobs), {} and the Slurm profile {}", files.snakefile.string(),
                files.jobs, files.config.string(), files.slurm_profile.string());
      return kExitOk;
    }
    if (*digest) return command_digest(session_dir, digest_folders);
    if (*defaults) {
      std::fputs(default_options_yaml(built).c_str(), stdout);
      return kExitOk;
    }
    return command_status(session_dir, built);
  });
}
