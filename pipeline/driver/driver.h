#pragma once
// The `fourd` driver as a library: the stage table, completion records, the decision to skip
// a stage, the run loop and the status table. main.cpp only parses the command line and prints.
//
// Skipping. After a stage runs successfully the driver writes a completion record,
// `<first output folder>/.fourd_stage.json`, LAST (atomically). It holds the content hash of
// every input file, a hash of the options the stage sees (its `stages.<name>` section of
// session.yaml plus the top-level session config, both re-emitted canonically), the hash of the
// stage executable, and the hash of every output file.
//
// Oracle runs (docs/design.md "Oracle inputs"). A stage X asked for with --oracle X (or listed in
// session.yaml's `oracle:`) runs a second time as the variant "X_oracle": `fourd-X --oracle`,
// reading inputs derived from ground truth and writing X_oracle/, so validation can report the
// pipeline and the oracle numbers side by side. The ground-truth-derived inputs are made by the
// step "oracle" (`fourd-validate --prepare-oracle`, writing oracle/segment, oracle/reconstruct
// and oracle/align); an oracle variant reads those where ground truth stands in for its input
// (kPreparedOracleInputs: timewarp_oracle reads oracle/align, so it inherits no alignment
// error), and otherwise the output of its input stage's oracle variant (motionspace_oracle
// reads timewarp_oracle). A stage is skipped
// when all of these still match; it runs when any differs, when its record is missing (the
// driver deletes the record before starting a stage, so a crashed run never looks complete),
// when an upstream stage ran in the same invocation, or when --force is given.
#include <cstdint>
#include <filesystem>
#include <functional>
#include <map>
#include <optional>
#include <set>
#include <string>
#include <string_view>
#include <vector>

#include "pipeline/core/capture.h"
#include "pipeline/core/error.h"
#include "pipeline/core/frame_selection.h"
#include "pipeline/core/session.h"

namespace fourd::driver {

namespace fs = std::filesystem;

// A command-line mistake (unknown stage name, contradictory options): exit code kExitUsage.
using fourd::UsageError;

// One stage of the pipeline and the session folders it reads and writes.
// Members without a default of their own get {}, so that GCC does not warn about those a
// designated initializer leaves out.
struct StageSpec {
  std::string name{};                    // "segment"; its executable is fourd-<name>
  std::vector<std::string> inputs{};     // session sub-folders it reads
  std::vector<std::string> outputs{};    // sub-folders it writes; the first holds its record
  bool supports_oracle = false;          // accepts --oracle (DESIGN "Oracle inputs")
  fs::path executable{};                 // empty in stage_table(); set by built_stages()
  std::vector<std::string> arguments{};  // extra command-line arguments (oracle runs)
  std::string options_stage{};           // whose stages.<name> options it sees; empty: name
  // A per-frame stage (runs as frame-range jobs, see stage_jobs): the files each frame's job
  // writes, relative to the first output folder, with {take}, {camera} and {frame} (000000)
  // standing for the frame's names. Empty: the stage is one job.
  std::vector<std::string> frame_outputs{};
  bool per_frame() const { return !frame_outputs.empty(); }
  // A stage split along a tree of frames (align): a --tree job that plans branch jobs, the
  // branch jobs, and a --finish job; see stage_jobs. Its jobs' files live in <output>/.jobs/.
  bool tree_split = false;
};

// The folder of ground-truth-derived inputs, written by the "oracle" step.
inline constexpr const char* kOracleFolder = "oracle";
// Control scripts the user puts in the session (runtime/player.h); validation plays those
// that follow a path. No stage writes them.
inline constexpr const char* kPlayFolder = "play";
// What a studio hands over besides its frames (fourd-import writes them; no stage does):
// background plates of the empty studio, plates/<camera>/<index>.png, and masks it made
// itself, masks/<take>/<camera>/<frame>.png. Segment reads both.
inline constexpr const char* kPlatesFolder = "plates";
inline constexpr const char* kMasksFolder = "masks";
// Completion record file name, inside the stage's first output folder.
inline constexpr const char* kRecordFile = ".fourd_stage.json";
// Folder of a split stage's job hand-over files, inside its output folder (tree_split).
inline constexpr const char* kJobsFolder = ".jobs";

// Every stage in pipeline order (synth ... validate), without executables.
const std::vector<StageSpec>& stage_table();
// The stages of stage_table() whose executable `fourd-<name>` exists in `bin_dir`, in order.
// A stage that is not built is simply absent.
std::vector<StageSpec> built_stages(const fs::path& bin_dir);
// Folder holding the running executable (from /proc/self/exe): the stages live beside `fourd`.
fs::path executable_dir();

// Index of `name` in `stages`; UsageError listing the available names otherwise.
std::size_t find_stage(const std::vector<StageSpec>& stages, const std::string& name);

fs::path record_path(const fs::path& session_root, const StageSpec& stage);

// "<stage>_oracle": the name and output folder of a stage's oracle run.
inline std::string oracle_variant_name(const std::string& stage) { return stage + "_oracle"; }

// The oracle variants of the stages named in `oracle`, inserted into `plan` right after their
// stage, preceded by the oracle preparation step (run by `validate`, which must be in `built`).
// A variant reads, for each input folder X written by a stage, X_oracle (when that stage runs
// on oracle inputs too, or X_oracle exists) or else oracle/X. Throws UsageError for a stage
// that cannot take oracle inputs.
std::vector<StageSpec> with_oracle_variants(const fs::path& session_root,
                                            const std::vector<StageSpec>& plan,
                                            const std::vector<StageSpec>& built,
                                            const std::set<std::string>& oracle);

// Path relative to the session root ('/' separators) -> content hash (hex), sorted by path.
using FileHashes = std::map<std::string, std::string>;

// Hashes every regular file under the session sub-folders `folders` (recursively, following
// symlinks) with hash_result_file. Completion records are left out, so one stage's record
// never looks like a change to the stages that read its folders. Absent folders contribute
// nothing.
FileHashes hash_folders(const fs::path& session_root, const std::vector<std::string>& folders);

// A stage's outputs also record how its run went: the time and CPU it took (keys holding
// "seconds", ending in "cpu_s" or "_us", cost ratios of two timings), how it was split into
// jobs ("branch_jobs", and the files of its `.jobs/` folder), and logs. They differ from run to
// run, but they are not results: a rerun that only changes them leaves the downstream stages up
// to date.
bool is_run_measurement(std::string_view json_key);
// The content hash of one output file, run records aside: a *.log file and a *.md report (a
// rendering for people of the JSON beside it, times included) hash to a constant: their
// presence counts, not their bytes. A *.json file is hashed without its run measurements, a
// *.jsonl file line by line the same way, a *.csv table without the columns its header names
// as run measurements (a play's search_us); every other file (and one of these that does not
// parse) byte for byte. The files of a `.jobs/`
// folder (what a split stage's jobs hand each other: align's plan and branch files, as many as
// the run had jobs; the stage's last job checks them, nothing after it reads them) are not
// listed by hash_folders, folder_bytes or `fourd digest` at all.
std::uint64_t hash_result_file(const fs::path& path);
// Total size in bytes of the regular files under the session sub-folders `folders`.
std::uint64_t folder_bytes(const fs::path& session_root, const std::vector<std::string>& folders);

// Hash of what a stage's options are: the top-level session config (everything but `stages`,
// with defaults filled in) and the raw `stages.<stage>` section, both emitted canonically
// (sorted keys), so comments, key order and other stages' sections do not matter.
std::string options_hash(const Session& session, const std::string& stage);

// Everything a stage's result depends on, as seen before it runs.
struct StageFingerprint {
  FileHashes inputs;
  std::string options_hash;
  std::string executable_hash;
};
StageFingerprint fingerprint(const Session& session, const StageSpec& stage);

struct CompletionRecord {
  std::string stage;
  StageFingerprint fingerprint;
  FileHashes outputs;
  std::uint64_t output_bytes = 0;
  std::string finished;  // local time "YYYY-MM-DD HH:MM:SS"
  double seconds = 0;    // wall-clock duration of the run
  double cpu_seconds = 0;          // user + system CPU time of its processes
  std::uint64_t peak_rss_bytes = 0;  // largest resident set of any of its processes
};

// Reads a record; nullopt when it is absent or unreadable (a damaged record counts as none).
std::optional<CompletionRecord> read_record(const fs::path& path);
// Writes atomically; creates the folder if needed.
void write_record(const fs::path& path, const CompletionRecord& record);

// Why the stage must run, comparing its record with `current` and with its output files as
// they are now; an empty string when it is up to date.
std::string staleness(const fs::path& session_root, const StageSpec& stage,
                      const StageFingerprint& current);

// One job of a stage, the unit both `fourd run` and the generated workflow execute: the whole
// stage; for a per-frame stage, one take's range of frames; or the --finish job that checks a
// split stage's frames and writes its reports.
struct Job {
  std::string stage{};         // the stage (or oracle variant) name
  FrameSelection selection{};  // a range job: one take, one range
  bool finish = false;
  // A tree-split stage's job: the tree job (tree), or branch job `branch` of `branches`.
  bool tree = false;
  int branch = -1;
  int branches = 0;

  // "reconstruct", "reconstruct.walk.0-7", "reconstruct.finish", "align.tree", "align.branch1"
  std::string name() const;
  // Added to the stage's command line: --take T --frames A:B, --tree --branches B,
  // --branch K, or --finish.
  std::vector<std::string> arguments() const;
  // "tree", "branch<K>", or "" (see tree_job_part in stages/common/stage.h).
  std::string part() const;
  // Its log, relative to the session's logs/ (the stage writes it).
  std::string log_name() const { return job_log_name(stage, selection, part()); }
  // A tree-split stage's files of this job (tree: the plan; branch: its result), relative to
  // the session, given the stage's first output folder.
  std::string tree_job_file(const std::string& output_folder) const;
};

// The jobs `stage` runs as, in order: one job for a stage that is neither per-frame nor
// tree-split; a per-frame stage's takes cut into ranges of at most `frames_per_job` frames
// (0: one range per take), then the finish job; a tree-split stage's tree job, its
// `branch_jobs` branch jobs, then the finish job.
std::vector<Job> stage_jobs(const StageSpec& stage, const CaptureIndex& capture,
                            int frames_per_job, int branch_jobs = 1);

// The session's capture (takes and frame counts, checked as scan_capture does).
CaptureIndex session_capture(const Session& session);

// What `fourd run` was asked to do.
struct RunRequest {
  std::string only;              // run just this stage
  std::string from;              // run this stage and every one after it
  bool force = false;            // rerun the selected stages even if up to date
  std::set<std::string> oracle;  // stages also run on oracle inputs (--oracle STAGE), besides
                                 // those listed in session.yaml's `oracle:`
  int threads = 0;               // passed to the stages; 0 = all cores
  bool verbose = false;          // passed to the stages
  int frames_per_job = 0;        // per-frame stages: frames per job (0: one job per take)
  int branch_jobs = 1;           // tree-split stages (align): branch jobs
};

// Whether synth belongs to this session's runs: only when session.yaml has a stages.synth
// section. Without one, capture/ is a real capture and synth must never overwrite it.
bool session_uses_synth(const Session& session);

// Whether `stage`'s first output folder holds an import record (kImportRecordFile).
bool is_imported(const fs::path& session_root, const StageSpec& stage);

// The built stages the driver leaves alone, each with the reason: the imported ones (their
// folders are the user's), and those made unnecessary by them - a stage every reader of whose
// outputs is imported or itself unnecessary (validation aside: it reads whatever is there),
// and, in a session with imported stages but no capture/, the stages that need the images.
std::map<std::string, std::string> stages_left_alone(const Session& session,
                                                     const std::vector<StageSpec>& built);

// The stages a run considers, in order: `built` narrowed by only/from, without synth when the
// session does not use it and without the stages_left_alone, with the oracle variants of the
// requested stages. Throws UsageError for unknown names, --only with --from, an oracle request
// for a stage that cannot take one, --only synth on a real capture, or --only of a stage left
// alone (an imported one: its folder is the user's).
std::vector<StageSpec> plan_run(const Session& session, const std::vector<StageSpec>& built,
                                const RunRequest& request);

// What a finished child process used (from wait4's rusage).
struct ProcessUsage {
  double cpu_seconds = 0;            // user + system
  std::uint64_t peak_rss_bytes = 0;  // maximum resident set size
};

// Runs one stage executable as a child process (stderr and stdout shared with the driver):
// `<executable> <session> [arguments...] [job arguments...] [--threads N] [-v]`. Returns its exit code,
// 128 + signal number when it was killed; `usage` (when given) receives what it used. Throws
// IoError when it cannot be started.
int run_stage_process(const StageSpec& stage, const fs::path& session_root, int threads,
                      bool verbose, const std::vector<std::string>& job_arguments = {},
                      ProcessUsage* usage = nullptr);

// The defaults of every option of every built stage, as one YAML document with a `stages:`
// mapping (what config/defaults.yaml holds), gathered from `fourd-<stage> --print-defaults`.
std::string default_options_yaml(const std::vector<StageSpec>& built);

struct StageEvent {
  enum class Kind { kSkipped, kStarted, kFinished, kFailed };
  Kind kind;
  std::size_t index = 0;  // 1-based position in the plan
  std::size_t count = 0;  // stages in the plan
  std::string stage;
  std::string reason;  // why it runs, or why it is skipped
  double seconds = 0;  // kFinished/kFailed: duration
  ProcessUsage usage;  // kFinished/kFailed: CPU time (all jobs), peak memory (largest job)
  int exit_code = 0;   // kFailed
  fs::path log_file;   // the stage's own log (kFailed: the failing job's)
  std::size_t jobs = 1;  // kFinished: the jobs the stage ran as
};

struct RunResult {
  int exit_code = kExitOk;   // the failing stage's exit code, else 0
  std::string failed_stage;  // empty on success
  fs::path log_file;         // log of the failing stage
  std::vector<std::string> ran;
  std::vector<std::string> skipped;
};

// Opens the session (InputError when the folder does not exist), plans and runs the stages,
// stopping at the first failure. `on_event` is told about every stage (may be empty).
RunResult run_pipeline(const fs::path& session_dir, const std::vector<StageSpec>& built,
                       const RunRequest& request,
                       const std::function<void(const StageEvent&)>& on_event);

struct StageStatus {
  enum class State { kDone, kChanged, kNotRun, kIncomplete, kNotUsed, kImported };
  std::string stage;
  State state = State::kNotRun;
  std::string detail;                      // what changed, or why not used
  std::optional<CompletionRecord> record;  // the last successful run, if any
  std::uint64_t output_bytes = 0;          // size of its output folders now
  // Entries of the `warnings` list of its report (<first output>/report.json): frames or
  // cameras the stage could not do well, which it flagged rather than passed on silently.
  std::size_t warnings = 0;
};
const char* state_name(StageStatus::State state);

// The state of every built stage of the session (and of the oracle variants session.yaml asks
// for), in order (InputError if it does not exist). A done stage whose upstream stage would
// rerun is reported as changed.
std::vector<StageStatus> session_status(const fs::path& session_dir,
                                        const std::vector<StageSpec>& built);

}  // namespace fourd::driver
