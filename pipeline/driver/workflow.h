#pragma once
// `fourd workflow`: the session's jobs (stage_jobs, the same split `fourd run` uses) as a
// Snakemake workflow, so an existing engine runs them on many cores or a Slurm cluster.
//
// Written to <session>/workflow/:
//   Snakefile        one rule per job; it calls the stage executable with the job's
//                    --take/--frames (or --tree/--branch/--finish), declares the job's inputs
//                    and outputs (per-frame stages: the frames' files; align's tree and branch
//                    jobs: their files in align/.jobs/; other jobs: a marker file
//                    workflow/done/<stage> touched after success), its log (logs/<job>.log,
//                    written by the stage), its threads and memory, and a benchmark file
//                    (workflow/benchmarks/<job>.tsv: Snakemake's measure of its wall time,
//                    peak memory and CPU time, from which the requests are set).
//   config.yaml      the executables' folder, and per stage the threads, memory (MB) and
//                    run time (minutes) its jobs request; edit them for bigger sessions.
//   profiles/slurm/  a Snakemake profile that submits every job with sbatch, requesting the
//                    rule's threads and memory.
#include <filesystem>
#include <map>
#include <string>
#include <vector>

#include "pipeline/driver/driver.h"

namespace fourd::driver {

// What one job of a stage asks of a machine.
struct JobCost {
  int threads = 1;
  int mem_mb = 1000;
  int minutes = 10;
};

// Requests per stage (options_stage name), from the peak memory and time measured per job on
// the workflow test session (docs/scale_plan.md), with headroom; written to config.yaml, where
// they are edited for bigger images. Stages not listed get JobCost{}.
const std::map<std::string, JobCost>& default_job_costs();

struct WorkflowRequest {
  int frames_per_job = 8;  // per-frame stages: frames per job
  int branch_jobs = 4;     // tree-split stages (align): branch jobs
  std::set<std::string> oracle;  // as RunRequest::oracle
};

struct WorkflowFiles {
  fs::path snakefile, config, slurm_profile;
  std::size_t jobs = 0;
};

// Writes the workflow of every stage after synth (synth, when the session uses it, must have
// made capture/ already: the jobs are cut from its takes). Throws InputError when there is no
// capture, UsageError for a bad request.
WorkflowFiles write_workflow(const fs::path& session_dir, const std::vector<StageSpec>& built,
                             const WorkflowRequest& request);

}  // namespace fourd::driver
