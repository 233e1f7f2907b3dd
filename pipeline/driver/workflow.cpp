#include "pipeline/driver/workflow.h"

#include <fmt/format.h>

#include <cctype>
#include <nlohmann/json.hpp>

#include "pipeline/core/camera.h"
#include "pipeline/core/colmap_model.h"
#include "pipeline/core/files.h"
#include "pipeline/core/log.h"

namespace fourd::driver {
namespace {

constexpr const char* kWorkflowFolder = "workflow";

// A quoted string that is valid in Python and YAML alike.
std::string py_string(const std::string& s) { return nlohmann::json(s).dump(); }

// One word of the rule's shell command; Snakemake formats the command, so braces double.
std::string shell_word(const std::string& s) {
  bool plain = !s.empty();
  for (char c : s) {
    plain = plain && (std::isalnum(static_cast<unsigned char>(c)) || std::string("_.:,/-=").find(c) != std::string::npos);
  }
  std::string out;
  if (plain) {
    out = s;
  } else {
    out = "'";
    for (char c : s) out += c == '\'' ? std::string("'\\''") : std::string(1, c);
    out += "'";
  }
  std::string escaped;
  for (char c : out) escaped += (c == '{' || c == '}') ? std::string(2, c) : std::string(1, c);
  return escaped;
}

std::string rule_name(const Job& job) {
  std::string n = job.name();
  for (char& c : n) {
    if (!std::isalnum(static_cast<unsigned char>(c))) c = '_';
  }
  return n;
}

std::string marker(const std::string& stage) {
  return fmt::format("{}/done/{}", kWorkflowFolder, stage);
}

std::string replace_all(std::string s, const std::string& what, const std::string& with) {
  for (std::size_t at = s.find(what); at != std::string::npos; at = s.find(what, at + with.size())) {
    s.replace(at, what.size(), with);
  }
  return s;
}

// The files a per-frame stage writes for the frames of `selection` (one take, its ranges).
std::vector<std::string> frame_files(const StageSpec& stage, const FrameSelection& selection,
                                     int frame_count, const std::vector<Camera>& cameras) {
  std::vector<std::string> files;
  for (int f = 0; f < frame_count; ++f) {
    if (!selection.selects(selection.take, f)) continue;
    for (const std::string& pattern : stage.frame_outputs) {
      std::string p = replace_all(pattern, "{take}", selection.take);
      p = replace_all(p, "{frame}", frame_name(f));
      const std::string folder = stage.outputs.front() + "/";
      if (p.find("{camera}") == std::string::npos) {
        files.push_back(folder + p);
      } else {
        for (const Camera& c : cameras) files.push_back(folder + replace_all(p, "{camera}", c.name));
      }
    }
  }
  return files;
}

// The stage of `plan` that writes the session folder `folder` (exactly, or a parent of it:
// "oracle/segment" is written by the step "oracle"); nullptr for raw data.
const StageSpec* producer_of(const std::vector<StageSpec>& plan, const std::string& folder) {
  for (const StageSpec& s : plan) {
    for (const std::string& out : s.outputs) {
      if (folder == out || folder.rfind(out + "/", 0) == 0) return &s;
    }
  }
  return nullptr;
}

std::string list_block(const char* key, const std::vector<std::string>& items) {
  if (items.empty()) return "";
  std::string out = fmt::format("    {}:\n", key);
  for (const std::string& i : items) out += fmt::format("        {},\n", py_string(i));
  return out;
}

}  // namespace

const std::map<std::string, JobCost>& default_job_costs() {
  // Measured (docs/scale_plan.md, Snakemake benchmarks of 8-camera 320x240 jobs of 6 frames
  // on a busy 2-core machine): segment 67 MB and 14 s per job, reconstruct 128 MB and 85 s,
  // align 56 MB and 665 s for 80 frames. Requests: about 4x the memory and 5x the time. The
  // stages after align were not measured: their requests are generous guesses to edit.
  static const std::map<std::string, JobCost> costs = {
      {"segment", {1, 256, 5}},    {"reconstruct", {1, 512, 10}}, {"align", {2, 256, 60}},
      {"timewarp", {2, 2000, 30}}, {"motionspace", {2, 2000, 30}}, {"texture", {2, 2000, 30}},
      {"graph", {2, 2000, 30}},    {"validate", {2, 2000, 30}},
  };
  return costs;
}

namespace {

// The key of `stage`'s requests in config.yaml: the stage whose options it runs with.
std::string cost_key(const StageSpec& stage) {
  return stage.options_stage.empty() ? stage.name : stage.options_stage;
}

// The done-markers of the stages of `plan` that write `stage`'s inputs, sorted, once each.
std::vector<std::string> upstream_markers(const std::vector<StageSpec>& plan,
                                          const StageSpec& stage) {
  std::vector<std::string> inputs;
  for (const std::string& folder : stage.inputs) {
    const StageSpec* p = producer_of(plan, folder);
    if (p != nullptr && p != &stage) inputs.push_back(marker(p->name));
  }
  std::sort(inputs.begin(), inputs.end());
  inputs.erase(std::unique(inputs.begin(), inputs.end()), inputs.end());
  return inputs;
}

// The session's calibration files, relative to it, sorted.
std::vector<std::string> calibration_files(const Session& session) {
  std::vector<std::string> files;
  for (const auto& e : fs::directory_iterator(session.calibration_dir())) {
    if (e.is_regular_file() && e.path().filename().string().front() != '.') {
      files.push_back("calibration/" + e.path().filename().string());
    }
  }
  std::sort(files.begin(), files.end());
  return files;
}

// One rule: its inputs, outputs (the stage's done-marker unless `job_outputs`), log,
// benchmark, resources and command.
std::string rule_text(const StageSpec& stage, const Job& job, const std::string& rule,
                      const std::vector<std::string>& inputs,
                      const std::vector<std::string>& outputs, bool job_outputs) {
  std::string command = shell_word(fs::path(stage.executable).filename().string());
  command = "\"{config[bin]}/\"" + command + " .";
  for (const std::string& a : stage.arguments) command += ' ' + shell_word(a);
  for (const std::string& a : job.arguments()) command += ' ' + shell_word(a);
  command += " --threads {threads}";
  std::string text = fmt::format("rule {}:\n", rule);
  text += list_block("input", inputs);
  if (job_outputs) {
    text += list_block("output", outputs);
  } else {
    text += fmt::format("    output:\n        touch({}),\n", py_string(marker(stage.name)));
  }
  text += fmt::format("    log:\n        {},\n", py_string("logs/" + job.log_name()));
  // Snakemake measures every job (wall time, peak memory, CPU time): the costs to request.
  text += fmt::format("    benchmark:\n        {},\n",
                      py_string(fmt::format("{}/benchmarks/{}.tsv", kWorkflowFolder, job.name())));
  text += fmt::format("    threads: config[\"stages\"][{0}][\"threads\"]\n"
                      "    resources:\n"
                      "        mem_mb=config[\"stages\"][{0}][\"mem_mb\"],\n"
                      "        runtime=config[\"stages\"][{0}][\"minutes\"],\n",
                      py_string(cost_key(stage)));
  text += fmt::format("    shell:\n        {}\n\n", py_string(command));
  return text;
}

// The Snakefile's rules, job by job, and what the file lists besides them.
class RuleWriter {
 public:
  RuleWriter(const Session& session, const std::vector<StageSpec>& plan,
             const CaptureIndex& capture, const std::vector<Camera>& cameras)
      : session_(session),
        plan_(plan),
        capture_(capture),
        cameras_(cameras),
        calibration_files_(calibration_files(session)) {}

  // The rules of every job of `stage` (an element of the plan).
  void add_stage(const StageSpec& stage, const WorkflowRequest& request);

  std::string rules;
  std::string frame_jobs;  // (stage, take, first, last, log) of every range job
  std::vector<std::string> all;
  std::size_t job_count = 0;

 private:
  std::vector<std::string> range_inputs(const StageSpec& stage, const Job& job, int frames) const;

  const Session& session_;
  const std::vector<StageSpec>& plan_;
  const CaptureIndex& capture_;
  const std::vector<Camera>& cameras_;
  const std::vector<std::string> calibration_files_;
  std::set<std::string> names_;
};

void RuleWriter::add_stage(const StageSpec& stage, const WorkflowRequest& request) {
  const std::vector<Job> jobs =
      stage_jobs(stage, capture_, request.frames_per_job, request.branch_jobs);
  // What the finish job waits for: every range job's frame files, or every branch job's result.
  std::vector<std::string> stage_frame_files;
  std::string plan_file;  // a tree-split stage's tree job output
  for (const Job& job : jobs) {
    const std::string rule = rule_name(job);
    if (!names_.insert(rule).second) {
      throw UsageError(fmt::format("two jobs would both be rule {}: rename a take so that take "
                                   "names differ in more than punctuation", rule));
    }
    std::vector<std::string> inputs, outputs;
    const bool range_job = stage.per_frame() && !job.finish;
    const bool tree_part = stage.tree_split && !job.finish;
    if (tree_part) {
      const std::string file = job.tree_job_file(stage.outputs.front());
      outputs.push_back(file);
      if (job.tree) {
        plan_file = file;
        inputs = upstream_markers(plan_, stage);
      } else {
        inputs.push_back(plan_file);
        stage_frame_files.push_back(file);
      }
    } else if (range_job) {
      const int frames = capture_.take(job.selection.take).frame_count;
      outputs = frame_files(stage, job.selection, frames, cameras_);
      stage_frame_files.insert(stage_frame_files.end(), outputs.begin(), outputs.end());
      inputs = range_inputs(stage, job, frames);
      frame_jobs += fmt::format("    ({}, {}, {}, {}, {}),\n", py_string(stage.name),
                                py_string(job.selection.take), job.selection.ranges[0].first,
                                job.selection.ranges[0].last, py_string("logs/" + job.log_name()));
    } else {
      inputs = job.finish ? stage_frame_files : upstream_markers(plan_, stage);
      all.push_back(marker(stage.name));
    }
    rules += rule_text(stage, job, rule, inputs, outputs, range_job || tree_part);
    ++job_count;
  }
}

// A range job's inputs: its frames' files of the per-frame stages before it, the other
// stages' done-markers, its capture images and the calibration.
std::vector<std::string> RuleWriter::range_inputs(const StageSpec& stage, const Job& job,
                                                  int frames) const {
  std::vector<std::string> inputs;
  for (const std::string& folder : stage.inputs) {
    const StageSpec* p = producer_of(plan_, folder);
    if (p != nullptr && p->per_frame()) {
      std::vector<std::string> f = frame_files(*p, job.selection, frames, cameras_);
      inputs.insert(inputs.end(), f.begin(), f.end());
    } else if (p != nullptr) {
      inputs.push_back(marker(p->name));
    } else if (folder == "capture") {
      for (int f = 0; f < frames; ++f) {
        if (!job.selection.selects(job.selection.take, f)) continue;
        for (const Camera& c : cameras_) {
          inputs.push_back(fs::relative(session_.capture_image(job.selection.take, c.name, f),
                                        session_.root()).generic_string());
        }
      }
    } else if (folder == "calibration") {
      inputs.insert(inputs.end(), calibration_files_.begin(), calibration_files_.end());
    }
  }
  return inputs;
}

// The Snakefile: how to run it, the frame-range jobs, the report of skipped frames, the rules.
std::string snakefile_text(const fs::path& root, const WorkflowFiles& files,
                           const WorkflowRequest& request, const RuleWriter& rules) {
  return fmt::format(
      "# Generated by `fourd workflow` from {session}/session.yaml: {jobs} jobs, per-frame stages\n"
      "# cut into jobs of at most {fpj} frames of one take. Regenerate it when the capture or the\n"
      "# stages change. Every rule runs one job of a stage executable (the same jobs as\n"
      "# `fourd run`); its log is the stage's own, logs/<job>.log.\n"
      "#   snakemake -s {snakefile} --cores 2 --show-failed-logs\n"
      "#   snakemake -s {snakefile} --profile {profile}\n"
      "import json\n"
      "import os\n\n"
      "configfile: os.path.join(workflow.basedir, \"config.yaml\")\n"
      "workdir: config[\"session\"]\n\n"
      "# (stage, take, first frame, last frame, log) of every frame-range job.\n"
      "FRAME_JOBS = [\n{frame_jobs}]\n\n"
      "onsuccess:\n"
      "    # Frames a per-frame stage could not process are reported, not hidden.\n"
      "    for stage in sorted({{job[0] for job in FRAME_JOBS}}):\n"
      "        try:\n"
      "            skipped = json.load(open(f\"{{stage}}/report.json\"))[\"summary\"][\"skipped\"]\n"
      "        except (OSError, KeyError, ValueError):\n"
      "            continue\n"
      "        for s in skipped:\n"
      "            log = next(j[4] for j in FRAME_JOBS if j[0] == stage and j[1] == s[\"take\"]\n"
      "                       and j[2] <= s[\"frame\"] <= j[3])\n"
      "            print(f\"fourd: {{stage}}: take {{s['take']}} frame {{s['frame']}} failed: \"\n"
      "                  f\"{{s['because']}} (log: {{log}})\")\n\n"
      "localrules: all\n\n"
      "rule all:\n"
      "{all}"
      "    default_target: True\n\n"
      "{rules}",
      fmt::arg("session", root.string()), fmt::arg("jobs", rules.job_count),
      fmt::arg("fpj", request.frames_per_job), fmt::arg("snakefile", files.snakefile.string()),
      fmt::arg("profile", files.slurm_profile.string()), fmt::arg("frame_jobs", rules.frame_jobs),
      fmt::arg("all", list_block("input", rules.all)), fmt::arg("rules", rules.rules));
}

// config.yaml: the session, the executables and every stage's requests.
std::string config_text(const fs::path& root, const std::vector<StageSpec>& plan,
                        const WorkflowRequest& request) {
  std::string config = fmt::format(
      "# fourd workflow settings (written by `fourd workflow`). The requests per stage are what\n"
      "# one job asks of a machine: threads, memory in MB and run time in minutes, measured on\n"
      "# the tiny sample with headroom; raise them for bigger images or more cameras.\n"
      "session: {}\nbin: {}\nframes_per_job: {}\nstages:\n",
      py_string(root.string()), py_string(fs::absolute(plan.front().executable).parent_path().string()),
      request.frames_per_job);
  std::set<std::string> cost_keys;
  for (const StageSpec& s : plan) cost_keys.insert(cost_key(s));
  for (const std::string& key : cost_keys) {
    auto it = default_job_costs().find(key);
    const JobCost cost = it != default_job_costs().end() ? it->second : JobCost{};
    config += fmt::format("  {}: {{threads: {}, mem_mb: {}, minutes: {}}}\n", py_string(key),
                          cost.threads, cost.mem_mb, cost.minutes);
  }
  return config;
}

// The Slurm profile of the workflow.
constexpr const char* kSlurmProfile =
    "# Snakemake profile: every job of the fourd workflow is one Slurm job (sbatch) asking for\n"
    "# its rule's threads, memory and time (workflow/config.yaml). Slurm's own output goes to\n"
    "# logs/slurm/; the stage's log to logs/<job>.log.\n"
    "cluster: \"mkdir -p logs/slurm && sbatch --parsable --job-name=fourd.{rule} "
    "--cpus-per-task={threads} --mem={resources.mem_mb} --time={resources.runtime} "
    "--output=logs/slurm/{rule}.%j.log\"\n"
    "cluster-cancel: scancel\n"
    "jobs: 500\n"
    "max-jobs-per-second: 20\n"
    "latency-wait: 60\n"
    "rerun-incomplete: true\n"
    "show-failed-logs: true\n";

}  // namespace

WorkflowFiles write_workflow(const fs::path& session_dir, const std::vector<StageSpec>& built,
                             const WorkflowRequest& request) {
  if (request.frames_per_job < 1) throw UsageError("--frames-per-job must be at least 1");
  Session session = Session::open(session_dir);
  const fs::path root = fs::absolute(session.root()).lexically_normal();
  RunRequest run;
  run.oracle = request.oracle;
  std::vector<StageSpec> plan;
  for (StageSpec& s : plan_run(session, built, run)) {
    if (s.name != "synth") plan.push_back(std::move(s));
  }
  if (plan.empty()) throw UsageError("no stage after synth is built: nothing to run");
  const CaptureIndex capture = session_capture(session);
  const std::vector<Camera> cameras = read_colmap_model(session.calibration_dir());
  RuleWriter rules(session, plan, capture, cameras);
  for (const StageSpec& stage : plan) rules.add_stage(stage, request);

  const fs::path dir = root / kWorkflowFolder;
  WorkflowFiles files;
  files.snakefile = dir / "Snakefile";
  files.config = dir / "config.yaml";
  files.slurm_profile = dir / "profiles" / "slurm";
  files.jobs = rules.job_count;
  write_file_atomic(files.snakefile, snakefile_text(root, files, request, rules));
  write_file_atomic(files.config, config_text(root, plan, request));
  write_file_atomic(files.slurm_profile / "config.yaml", kSlurmProfile);
  return files;
}

}  // namespace fourd::driver
