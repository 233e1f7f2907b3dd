#include "pipeline/driver/driver.h"

#include <fmt/format.h>
#include <spawn.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <tbb/parallel_for.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <memory>
#include <nlohmann/json.hpp>

#include "pipeline/core/colmap_model.h"
#include "pipeline/core/files.h"
#include "pipeline/core/log.h"

extern char** environ;

namespace fourd::driver {
namespace {

constexpr const char* kRecordFormat = "fourd-stage-record";
constexpr int kRecordVersion = 1;

std::string join(const std::vector<std::string>& names, const char* sep = ", ") {
  std::string out;
  for (const auto& n : names) out += (out.empty() ? "" : sep) + n;
  return out;
}

std::vector<std::string> stage_names(const std::vector<StageSpec>& stages) {
  std::vector<std::string> names;
  for (const auto& s : stages) names.push_back(s.name);
  if (names.empty()) names.push_back("none");
  return names;
}

struct FileEntry {
  std::string relative;  // to the session root, '/' separators
  fs::path path;
  std::uint64_t size = 0;
};

// Every regular file under the given session sub-folders except completion records, sorted.
std::vector<FileEntry> list_files(const fs::path& root, const std::vector<std::string>& folders) {
  std::vector<FileEntry> files;
  for (const auto& folder : folders) {
    fs::path dir = root / folder;
    std::error_code ec;
    if (!fs::is_directory(dir, ec)) continue;
    fs::recursive_directory_iterator it(dir, fs::directory_options::follow_directory_symlink, ec);
    for (; !ec && it != fs::recursive_directory_iterator(); it.increment(ec)) {
      std::error_code fec;
      // A split stage's job hand-over files are not results (see hash_result_file).
      if (it->is_directory(fec) && it->path().filename() == kJobsFolder) {
        it.disable_recursion_pending();
        continue;
      }
      if (!it->is_regular_file(fec) || it->path().filename() == kRecordFile) continue;
      FileEntry e;
      e.path = it->path();
      e.relative = folder + "/" + e.path.lexically_relative(dir).generic_string();
      e.size = it->file_size(fec);
      files.push_back(std::move(e));
    }
    if (ec) throw IoError(fmt::format("cannot list {}: {}", dir.string(), ec.message()));
  }
  std::sort(files.begin(), files.end(),
            [](const FileEntry& a, const FileEntry& b) { return a.relative < b.relative; });
  return files;
}

// YAML -> JSON with every scalar as a string: nlohmann's dump() sorts object keys, which makes
// the text canonical (independent of key order, comments and formatting).
nlohmann::json yaml_to_json(const YAML::Node& node) {
  if (!node.IsDefined()) return nullptr;
  switch (node.Type()) {
    case YAML::NodeType::Map: {
      nlohmann::json obj = nlohmann::json::object();
      for (const auto& kv : node) obj[kv.first.as<std::string>()] = yaml_to_json(kv.second);
      return obj;
    }
    case YAML::NodeType::Sequence: {
      nlohmann::json arr = nlohmann::json::array();
      for (const auto& item : node) arr.push_back(yaml_to_json(item));
      return arr;
    }
    case YAML::NodeType::Scalar:
      return node.Scalar();
    default:
      return nullptr;
  }
}

nlohmann::json hashes_to_json(const FileHashes& files) {
  nlohmann::json obj = nlohmann::json::object();
  for (const auto& [path, hash] : files) obj[path] = hash;
  return obj;
}

FileHashes hashes_from_json(const nlohmann::json& obj) {
  FileHashes files;
  for (const auto& [path, hash] : obj.items()) files[path] = hash.get<std::string>();
  return files;
}

// "inputs changed: 2 modified, 1 added (capture/walk/cam00/000001.png, ...)"
std::string describe_difference(const char* what, const FileHashes& before, const FileHashes& now) {
  std::size_t modified = 0, added = 0, removed = 0;
  std::vector<std::string> examples;
  auto note = [&](const std::string& path) {
    if (examples.size() < 3) examples.push_back(path);
  };
  for (const auto& [path, hash] : now) {
    auto it = before.find(path);
    if (it == before.end()) {
      ++added;
      note(path);
    } else if (it->second != hash) {
      ++modified;
      note(path);
    }
  }
  for (const auto& [path, hash] : before) {
    if (!now.count(path)) {
      ++removed;
      note(path);
    }
  }
  std::vector<std::string> parts;
  if (modified) parts.push_back(fmt::format("{} modified", modified));
  if (added) parts.push_back(fmt::format("{} added", added));
  if (removed) parts.push_back(fmt::format("{} removed", removed));
  std::size_t total = modified + added + removed;
  return fmt::format("{} changed: {} ({}{})", what, join(parts), join(examples),
                     total > examples.size() ? ", ..." : "");
}

// Whether a stage reading `inputs` reads one of `folders` (folder -> the stage that writes
// it); `which` names that stage.
bool reads_any(const std::vector<std::string>& inputs,
               const std::map<std::string, std::string>& folders, std::string* which) {
  for (const auto& in : inputs) {
    auto it = folders.find(in);
    if (it != folders.end()) {
      *which = it->second;
      return true;
    }
  }
  return false;
}

}  // namespace

const std::vector<StageSpec>& stage_table() {
  // The data flow of docs/design.md "Stages". Segment has no oracle: nothing precedes it but the
  // capture. Validate reads every stage's outputs plus the ground truth, and plays the
  // session's control scripts (play/) on the assets.
  static const std::vector<StageSpec> table = {
      {.name = "synth", .outputs = {"capture", "calibration", "ground_truth", kPlatesFolder}},
      {.name = "segment",
       .inputs = {"capture", "calibration", kPlatesFolder, kMasksFolder},
       .outputs = {"segment"},
       .frame_outputs = {"{take}/{camera}/{frame}.png"}},
      // Its per-frame record (.json) is written last and also for a frame that failed.
      {.name = "reconstruct",
       .inputs = {"capture", "segment", "calibration"},
       .outputs = {"reconstruct"},
       .supports_oracle = true,
       .frame_outputs = {"{take}/{frame}.json"}},
      // Split along its shape tree: a tree job, branch jobs, a finish job (stage_jobs).
      {.name = "align",
       .inputs = {"reconstruct"},
       .outputs = {"align"},
       .supports_oracle = true,
       .tree_split = true},
      {.name = "timewarp", .inputs = {"align"}, .outputs = {"timewarp"}, .supports_oracle = true},
      {.name = "motionspace",
       .inputs = {"timewarp"},
       .outputs = {"motionspace"},
       .supports_oracle = true},
      {.name = "texture",
       .inputs = {"align", "capture", "calibration"},
       .outputs = {"texture"},
       .supports_oracle = true},
      {.name = "graph",
       .inputs = {"motionspace", "timewarp", "texture"},
       .outputs = {"graph", "asset"},
       .supports_oracle = true},
      {.name = "validate",
       .inputs = {"calibration", "capture", "ground_truth", "segment", "reconstruct", "align",
                  "timewarp", "motionspace", "texture", "graph", "asset", "oracle",
                  "reconstruct_oracle", "align_oracle", "timewarp_oracle", "motionspace_oracle",
                  "texture_oracle", "graph_oracle", "asset_oracle", kPlayFolder},
       .outputs = {"reports"}},
  };
  return table;
}

std::vector<StageSpec> built_stages(const fs::path& bin_dir) {
  std::vector<StageSpec> built;
  for (const auto& spec : stage_table()) {
    fs::path exe = bin_dir / ("fourd-" + spec.name);
    std::error_code ec;
    if (fs::is_regular_file(exe, ec) && ::access(exe.c_str(), X_OK) == 0) {
      built.push_back(spec);
      built.back().executable = exe;
    }
  }
  return built;
}

fs::path executable_dir() {
  std::error_code ec;
  fs::path self = fs::read_symlink("/proc/self/exe", ec);
  if (ec) throw IoError(fmt::format("cannot locate the fourd executable: {}", ec.message()));
  return self.parent_path();
}

std::size_t find_stage(const std::vector<StageSpec>& stages, const std::string& name) {
  for (std::size_t i = 0; i < stages.size(); ++i) {
    if (stages[i].name == name) return i;
  }
  const auto& all = stage_table();
  bool known =
      std::any_of(all.begin(), all.end(), [&](const StageSpec& s) { return s.name == name; });
  if (known) {
    throw UsageError(
        fmt::format("stage '{}' is not built (no fourd-{} beside fourd); available stages: {}",
                    name, name, join(stage_names(stages))));
  }
  throw UsageError(
      fmt::format("unknown stage '{}'; available stages: {}", name, join(stage_names(stages))));
}

fs::path record_path(const fs::path& session_root, const StageSpec& stage) {
  return session_root / stage.outputs.front() / kRecordFile;
}

std::vector<StageSpec> with_oracle_variants(const fs::path& session_root,
                                            const std::vector<StageSpec>& plan,
                                            const std::vector<StageSpec>& built,
                                            const std::set<std::string>& oracle) {
  if (oracle.empty()) return plan;
  // Folder -> the built stage that writes it (synth's folders are the raw data, not outputs).
  std::map<std::string, std::string> producer;
  for (const auto& s : built) {
    if (s.name == "synth") continue;
    for (const auto& out : s.outputs) producer[out] = s.name;
  }
  std::vector<StageSpec> out;
  bool prepared = false;
  for (const auto& stage : plan) {
    out.push_back(stage);
    if (!oracle.count(stage.name)) continue;
    if (!stage.supports_oracle) {
      std::vector<std::string> can;
      for (const auto& s : built) {
        if (s.supports_oracle) can.push_back(s.name);
      }
      throw UsageError(fmt::format(
          "--oracle {}: stage '{}' cannot take ground-truth inputs; stages that can: {}",
          stage.name, stage.name, can.empty() ? "none built" : join(can)));
    }
    if (!prepared) {
      auto validate = std::find_if(built.begin(), built.end(),
                                   [](const StageSpec& s) { return s.name == "validate"; });
      if (validate == built.end()) {
        throw UsageError("oracle runs need fourd-validate, which prepares their inputs");
      }
      StageSpec prepare;
      prepare.name = kOracleFolder;
      prepare.inputs = {"ground_truth"};
      prepare.outputs = {kOracleFolder};
      prepare.executable = validate->executable;
      prepare.arguments = {"--prepare-oracle"};
      out.insert(out.end() - 1, prepare);
      prepared = true;
    }
    StageSpec variant = stage;
    variant.name = oracle_variant_name(stage.name);
    variant.options_stage = stage.name;
    variant.arguments = {"--oracle"};
    variant.outputs = {oracle_variant_name(stage.name)};
    variant.supports_oracle = false;
    // The same rule as stage_input_dir() in the stages: what ground truth stands in for comes
    // from oracle/ (the stage then inherits no error); otherwise the oracle run of the producing
    // stage when there is one, else the copy under oracle/.
    for (auto& input : variant.inputs) {
      auto p = producer.find(input);
      if (p == producer.end()) continue;
      std::error_code ec;
      std::string chained = oracle_variant_name(input);
      if (is_prepared_oracle_input(input)) {
        input = std::string(kOracleFolder) + "/" + input;
      } else if (oracle.count(p->second) || fs::is_directory(session_root / chained, ec)) {
        input = chained;
      } else {
        input = std::string(kOracleFolder) + "/" + input;
      }
    }
    out.push_back(std::move(variant));
  }
  return out;
}

bool is_run_measurement(std::string_view key) {
  auto ends_with = [&](std::string_view tail) {
    return key.size() >= tail.size() && key.substr(key.size() - tail.size()) == tail;
  };
  return key.find("seconds") != std::string_view::npos || ends_with("cpu_s") ||
         ends_with("_us") || key.find("cost_ratio") != std::string_view::npos ||
         key == "branch_jobs";
}

namespace {

void drop_run_measurements(nlohmann::json* j) {
  if (j->is_object()) {
    for (auto it = j->begin(); it != j->end();) {
      if (is_run_measurement(it.key())) {
        it = j->erase(it);
      } else {
        drop_run_measurements(&it.value());
        ++it;
      }
    }
  } else if (j->is_array()) {
    for (auto& e : *j) drop_run_measurements(&e);
  }
}

std::vector<std::string_view> split_on(std::string_view text, char separator) {
  std::vector<std::string_view> parts;
  std::size_t start = 0;
  while (true) {
    const std::size_t end = text.find(separator, start);
    parts.push_back(text.substr(start, end == std::string_view::npos ? end : end - start));
    if (end == std::string_view::npos) return parts;
    start = end + 1;
  }
}

// One JSON document per line (transitions.jsonl), each without its run measurements; false
// when a line does not parse.
bool canonical_json_lines(const std::string& text, std::string* out) {
  for (std::string_view line : split_on(text, '\n')) {
    if (line.empty()) continue;
    nlohmann::json j = nlohmann::json::parse(line, nullptr, /*allow_exceptions=*/false);
    if (j.is_discarded()) return false;
    drop_run_measurements(&j);
    *out += j.dump();
    *out += '\n';
  }
  return true;
}

// A table with a header line (frames.csv) without the columns its header names as run
// measurements (a search's wall-clock search_us); false when a field is quoted (the split on
// commas would not be the table's) or the header names no such column.
bool canonical_csv(const std::string& text, std::string* out) {
  if (text.find('"') != std::string::npos) return false;
  const std::vector<std::string_view> lines = split_on(text, '\n');
  std::vector<char> keep;
  for (std::string_view name : split_on(lines.front(), ',')) keep.push_back(!is_run_measurement(name));
  if (std::all_of(keep.begin(), keep.end(), [](char k) { return k; })) return false;
  for (std::string_view line : lines) {
    const std::vector<std::string_view> fields = split_on(line, ',');
    for (std::size_t i = 0; i < fields.size(); ++i) {
      if (i < keep.size() && !keep[i]) continue;
      *out += fields[i];
      *out += ',';
    }
    *out += '\n';
  }
  return true;
}

}  // namespace

std::uint64_t hash_result_file(const fs::path& path) {
  const std::string ext = path.extension().string();
  if (ext == ".log" || ext == ".md") return hash_bytes("a log or a rendered report");
  if (ext == ".json") {
    nlohmann::json j = nlohmann::json::parse(read_file(path), nullptr, /*allow_exceptions=*/false);
    if (!j.is_discarded()) {
      drop_run_measurements(&j);
      return hash_bytes(j.dump());
    }
  }
  if (ext == ".jsonl" || ext == ".csv") {
    std::string canonical;
    const std::string text = read_file(path);
    if (ext == ".jsonl" ? canonical_json_lines(text, &canonical) : canonical_csv(text, &canonical)) {
      return hash_bytes(canonical);
    }
  }
  return hash_file(path);
}

FileHashes hash_folders(const fs::path& session_root, const std::vector<std::string>& folders) {
  std::vector<FileEntry> files = list_files(session_root, folders);
  std::vector<std::uint64_t> hashes(files.size());
  // Captures hold thousands of images: hash them in parallel (hash_file streams each file).
  tbb::parallel_for(std::size_t{0}, files.size(),
                    [&](std::size_t i) { hashes[i] = hash_result_file(files[i].path); });
  FileHashes out;
  for (std::size_t i = 0; i < files.size(); ++i)
    out.emplace(files[i].relative, hash_hex(hashes[i]));
  return out;
}

std::uint64_t folder_bytes(const fs::path& session_root, const std::vector<std::string>& folders) {
  std::uint64_t bytes = 0;
  for (const auto& f : list_files(session_root, folders)) bytes += f.size;
  return bytes;
}

std::string options_hash(const Session& session, const std::string& stage) {
  nlohmann::json top = yaml_to_json(to_yaml(session.config()));
  top.erase("stages");
  top.erase("presets");  // what they say is hashed below, not their file names
  nlohmann::json sections = nlohmann::json::array();
  for (const auto& section : session.stage_sections(stage)) sections.push_back(yaml_to_json(section));
  std::string text = "session:" + top.dump() + "\nstages." + stage + ":" + sections.dump();
  return hash_hex(hash_bytes(text));
}

StageFingerprint fingerprint(const Session& session, const StageSpec& stage) {
  StageFingerprint fp;
  fp.inputs = hash_folders(session.root(), stage.inputs);
  fp.options_hash =
      options_hash(session, stage.options_stage.empty() ? stage.name : stage.options_stage);
  if (!stage.executable.empty()) fp.executable_hash = hash_hex(hash_file(stage.executable));
  return fp;
}

std::optional<CompletionRecord> read_record(const fs::path& path) {
  std::error_code ec;
  if (!fs::is_regular_file(path, ec)) return std::nullopt;
  try {
    nlohmann::json j = nlohmann::json::parse(read_file(path));
    if (j.at("format").get<std::string>() != kRecordFormat ||
        j.at("version").get<int>() != kRecordVersion) {
      return std::nullopt;
    }
    CompletionRecord r;
    r.stage = j.at("stage").get<std::string>();
    r.fingerprint.options_hash = j.at("options_hash").get<std::string>();
    r.fingerprint.executable_hash = j.at("executable_hash").get<std::string>();
    r.fingerprint.inputs = hashes_from_json(j.at("inputs"));
    r.outputs = hashes_from_json(j.at("outputs"));
    r.output_bytes = j.at("output_bytes").get<std::uint64_t>();
    r.finished = j.at("finished").get<std::string>();
    r.seconds = j.at("seconds").get<double>();
    r.cpu_seconds = j.value("cpu_seconds", 0.0);
    r.peak_rss_bytes = j.value("peak_rss_bytes", std::uint64_t{0});
    return r;
  } catch (const nlohmann::json::exception&) {
    return std::nullopt;
  } catch (const IoError&) {
    return std::nullopt;
  }
}

void write_record(const fs::path& path, const CompletionRecord& r) {
  nlohmann::json j;
  j["format"] = kRecordFormat;
  j["version"] = kRecordVersion;
  j["stage"] = r.stage;
  j["options_hash"] = r.fingerprint.options_hash;
  j["executable_hash"] = r.fingerprint.executable_hash;
  j["finished"] = r.finished;
  j["seconds"] = r.seconds;
  j["cpu_seconds"] = r.cpu_seconds;
  j["peak_rss_bytes"] = r.peak_rss_bytes;
  j["output_bytes"] = r.output_bytes;
  j["inputs"] = hashes_to_json(r.fingerprint.inputs);
  j["outputs"] = hashes_to_json(r.outputs);
  write_file_atomic(path, j.dump(1) + "\n");
}

std::string staleness(const fs::path& session_root, const StageSpec& stage,
                      const StageFingerprint& current) {
  fs::path path = record_path(session_root, stage);
  std::optional<CompletionRecord> record = read_record(path);
  if (!record) {
    std::error_code ec;
    return fs::exists(path, ec)
               ? "completion record unreadable"
               : "no completion record (never run, or the last run did not finish)";
  }
  const StageFingerprint& before = record->fingerprint;
  if (record->stage != stage.name)
    return fmt::format("completion record is for stage '{}'", record->stage);
  if (before.executable_hash != current.executable_hash) return "stage executable changed";
  if (before.options_hash != current.options_hash) return "options changed (session.yaml)";
  if (before.inputs != current.inputs)
    return describe_difference("inputs", before.inputs, current.inputs);
  FileHashes outputs = hash_folders(session_root, stage.outputs);
  if (outputs != record->outputs) return describe_difference("outputs", record->outputs, outputs);
  return "";
}

// The stages session.yaml's `oracle:` names that are built (an unbuilt one is simply absent,
// like the stage itself).
std::set<std::string> configured_oracle(const Session& session, const std::vector<StageSpec>& built) {
  std::set<std::string> out;
  for (const auto& name : session.config().oracle) {
    if (std::any_of(built.begin(), built.end(), [&](const StageSpec& s) { return s.name == name; })) {
      out.insert(name);
    }
  }
  return out;
}

bool session_uses_synth(const Session& session) {
  return session.has_stage_section("synth");
}

bool is_imported(const fs::path& session_root, const StageSpec& stage) {
  std::error_code ec;
  return fs::is_regular_file(session_root / stage.outputs.front() / kImportRecordFile, ec);
}

std::map<std::string, std::string> stages_left_alone(const Session& session,
                                                     const std::vector<StageSpec>& built) {
  const fs::path& root = session.root();
  std::map<std::string, std::string> alone;
  for (const auto& s : built) {
    if (s.name != "synth" && is_imported(root, s)) {
      alone[s.name] = fmt::format("imported ({}/{}): kept as supplied; delete that record to "
                                  "compute it instead",
                                  s.outputs.front(), kImportRecordFile);
    }
  }
  if (alone.empty()) return alone;
  std::error_code ec;
  const bool no_capture = !fs::is_directory(session.capture_dir(), ec);
  auto reads = [](const StageSpec& reader, const std::vector<std::string>& folders) {
    return std::any_of(reader.inputs.begin(), reader.inputs.end(), [&](const std::string& in) {
      return std::find(folders.begin(), folders.end(), in) != folders.end();
    });
  };
  // From the last stage back, so that a stage's readers are decided before it.
  for (auto it = built.rbegin(); it != built.rend(); ++it) {
    const StageSpec& s = *it;
    if (s.name == "synth" || s.name == "validate" || alone.count(s.name)) continue;
    if (no_capture && reads(s, {"capture"})) {
      alone[s.name] = "not needed: the session has no capture/, and its imported stages stand "
                      "without one";
      continue;
    }
    std::vector<std::string> readers;
    bool all_alone = true;
    for (const auto& r : built) {
      if (r.name == "validate" || r.name == s.name || !reads(r, s.outputs)) continue;
      readers.push_back(r.name);
      all_alone = all_alone && alone.count(r.name) > 0;
    }
    if (!readers.empty() && all_alone) {
      alone[s.name] = fmt::format("not needed: only {} read(s) its outputs, and that is left alone",
                                  join(readers));
    }
  }
  return alone;
}

std::vector<StageSpec> plan_run(const Session& session, const std::vector<StageSpec>& built,
                                const RunRequest& request) {
  if (!request.only.empty() && !request.from.empty()) {
    throw UsageError("--only and --from cannot be combined");
  }
  for (const auto& name : request.oracle) find_stage(built, name);  // known and built
  std::set<std::string> oracle = request.oracle;
  for (const auto& name : configured_oracle(session, built)) oracle.insert(name);
  bool uses_synth = session_uses_synth(session);
  const std::map<std::string, std::string> alone = stages_left_alone(session, built);
  std::vector<StageSpec> plan;
  if (!request.only.empty()) {
    const StageSpec& spec = built[find_stage(built, request.only)];
    if (spec.name == "synth" && !uses_synth) {
      throw UsageError(fmt::format(
          "--only synth: {} has no stages.synth section, so capture/ is a real capture that "
          "synth must not replace; add a stages.synth section to synthesize one",
          session.config_path().string()));
    }
    if (auto a = alone.find(spec.name); a != alone.end()) {
      throw UsageError(fmt::format("--only {}: {}", spec.name, a->second));
    }
    plan.push_back(spec);
  } else {
    std::size_t start = request.from.empty() ? 0 : find_stage(built, request.from);
    for (std::size_t i = start; i < built.size(); ++i) {
      if (built[i].name == "synth" && !uses_synth) continue;
      if (alone.count(built[i].name)) continue;
      plan.push_back(built[i]);
    }
  }
  // An oracle request (on the command line) for a stage that will not run is a mistake.
  for (const auto& name : request.oracle) {
    if (std::none_of(plan.begin(), plan.end(),
                     [&](const StageSpec& s) { return s.name == name; })) {
      throw UsageError(fmt::format("--oracle {}: stage '{}' is not part of this run (stages: {})",
                                   name, name, join(stage_names(plan))));
    }
  }
  return with_oracle_variants(session.root(), plan, built, oracle);
}

std::string Job::part() const {
  if (tree) return "tree";
  if (branch >= 0) return "branch" + std::to_string(branch);
  return {};
}

std::string Job::tree_job_file(const std::string& output_folder) const {
  const std::string jobs = output_folder + "/" + kJobsFolder + "/";
  if (tree) return jobs + "plan.bin";
  if (branch >= 0) return jobs + "branch" + std::to_string(branch) + ".bin";
  return {};
}

std::string Job::name() const {
  if (finish) return stage + ".finish";
  if (!part().empty()) return stage + "." + part();
  const std::string suffix = selection.job_suffix();
  return suffix.empty() ? stage : stage + "." + suffix;
}

std::vector<std::string> Job::arguments() const {
  if (finish) return {"--finish"};
  if (tree) return {"--tree", "--branches", std::to_string(branches)};
  if (branch >= 0) return {"--branch", std::to_string(branch)};
  std::vector<std::string> out;
  if (!selection.take.empty()) out.insert(out.end(), {"--take", selection.take});
  if (!selection.ranges.empty()) out.insert(out.end(), {"--frames", selection.frames_text()});
  return out;
}

std::vector<Job> stage_jobs(const StageSpec& stage, const CaptureIndex& capture,
                            int frames_per_job, int branch_jobs) {
  if (stage.tree_split) {
    if (branch_jobs < 1) throw UsageError("--branch-jobs must be at least 1");
    std::vector<Job> jobs;
    jobs.push_back(Job{.stage = stage.name, .tree = true, .branches = branch_jobs});
    for (int k = 0; k < branch_jobs; ++k) {
      jobs.push_back(Job{.stage = stage.name, .branch = k, .branches = branch_jobs});
    }
    jobs.push_back(Job{.stage = stage.name, .finish = true});
    return jobs;
  }
  if (!stage.per_frame()) return {Job{.stage = stage.name}};
  if (frames_per_job < 0) throw UsageError("--frames-per-job must be 0 or more");
  std::vector<Job> jobs;
  for (const TakeCapture& take : capture.takes) {
    const int step = frames_per_job > 0 ? frames_per_job : take.frame_count;
    for (int first = 0; first < take.frame_count; first += step) {
      Job job{.stage = stage.name,
              .selection = {take.name, {{first, std::min(first + step, take.frame_count) - 1}}}};
      jobs.push_back(std::move(job));
    }
  }
  jobs.push_back(Job{.stage = stage.name, .finish = true});
  return jobs;
}

CaptureIndex session_capture(const Session& session) {
  std::error_code ec;
  if (!fs::is_directory(session.capture_dir(), ec)) {
    throw InputError(fmt::format("{}: no capture yet (a synthetic session makes it with "
                                 "`fourd run {} --only synth`)",
                                 session.capture_dir().string(), session.root().string()));
  }
  CaptureIndex capture = scan_capture(session, read_colmap_model(session.calibration_dir()));
  if (capture.takes.empty()) {
    throw InputError(fmt::format("{}: no takes", session.capture_dir().string()));
  }
  return capture;
}

namespace {

// Runs `args` (args[0] is the executable) and waits for it; its standard output goes to
// `stdout_fd` when that is >= 0. Returns the exit code (128 + signal when killed); `usage`
// (when given) receives the child's CPU time and peak memory.
int spawn_and_wait(std::vector<std::string> args, int stdout_fd = -1,
                   ProcessUsage* usage = nullptr) {
  std::vector<char*> argv;
  for (auto& a : args) argv.push_back(a.data());
  argv.push_back(nullptr);

  std::fflush(stdout);
  std::fflush(stderr);
  posix_spawn_file_actions_t actions;
  ::posix_spawn_file_actions_init(&actions);
  if (stdout_fd >= 0) ::posix_spawn_file_actions_adddup2(&actions, stdout_fd, STDOUT_FILENO);
  pid_t pid = 0;
  int rc = ::posix_spawn(&pid, args[0].c_str(), &actions, nullptr, argv.data(), environ);
  ::posix_spawn_file_actions_destroy(&actions);
  if (rc != 0) throw IoError(fmt::format("cannot start {}: {}", args[0], std::strerror(rc)));
  int status = 0;
  struct rusage ru {};
  while (::wait4(pid, &status, 0, &ru) < 0) {
    if (errno != EINTR) {
      throw IoError(fmt::format("waiting for {} failed: {}", args[0], std::strerror(errno)));
    }
  }
  if (usage) {
    auto seconds = [](const timeval& t) { return double(t.tv_sec) + 1e-6 * double(t.tv_usec); };
    usage->cpu_seconds = seconds(ru.ru_utime) + seconds(ru.ru_stime);
    usage->peak_rss_bytes = std::uint64_t(ru.ru_maxrss) * 1024;  // Linux reports kilobytes
  }
  if (WIFEXITED(status)) return WEXITSTATUS(status);
  if (WIFSIGNALED(status)) return 128 + WTERMSIG(status);
  return kExitFailure;
}

}  // namespace

int run_stage_process(const StageSpec& stage, const fs::path& session_root, int threads,
                      bool verbose, const std::vector<std::string>& job_arguments,
                      ProcessUsage* usage) {
  std::vector<std::string> args = {stage.executable.string(), session_root.string()};
  args.insert(args.end(), stage.arguments.begin(), stage.arguments.end());
  args.insert(args.end(), job_arguments.begin(), job_arguments.end());
  if (threads > 0) {
    args.push_back("--threads");
    args.push_back(std::to_string(threads));
  }
  if (verbose) args.push_back("-v");
  return spawn_and_wait(std::move(args), -1, usage);
}

std::string default_options_yaml(const std::vector<StageSpec>& built) {
  YAML::Node stages(YAML::NodeType::Map);
  for (const auto& stage : built) {
    // Each stage prints its own sections (`fourd-<stage> --print-defaults`); read them back
    // through a temporary file so a stage's output is parsed whole.
    std::FILE* tmp = std::tmpfile();
    if (!tmp) throw IoError(fmt::format("cannot create a temporary file: {}", std::strerror(errno)));
    std::unique_ptr<std::FILE, int (*)(std::FILE*)> closer(tmp, &std::fclose);
    const int rc = spawn_and_wait({stage.executable.string(), "--print-defaults"}, ::fileno(tmp));
    if (rc != kExitOk) {
      throw IoError(fmt::format("{} --print-defaults failed with exit code {}",
                                stage.executable.string(), rc));
    }
    std::string text;
    std::rewind(tmp);
    char buffer[4096];
    for (std::size_t n; (n = std::fread(buffer, 1, sizeof buffer, tmp)) > 0;) text.append(buffer, n);
    YAML::Node sections;
    try {
      sections = YAML::Load(text);
    } catch (const YAML::Exception& e) {
      throw InputError(fmt::format("{} --print-defaults printed invalid YAML: {}",
                                   stage.executable.string(), e.what()));
    }
    if (!sections.IsMap()) continue;  // a stage with no options prints nothing
    for (const auto& kv : sections) stages[kv.first.as<std::string>()] = kv.second;
  }
  YAML::Node root(YAML::NodeType::Map);
  root["stages"] = stages;
  YAML::Emitter out;
  out << root;
  return fmt::format(
      "# Every stage's section of session.yaml with its defaults, as `fourd defaults` prints\n"
      "# them. Copy the sections you want to change into a session's stages:, or keep a set of\n"
      "# changes as a preset (config/presets/) and list it under presets: in session.yaml.\n"
      "# The tuned values behind these options are not options: docs/<stage>.md, \"Advanced\".\n"
      "{}\n",
      out.c_str());
}

RunResult run_pipeline(const fs::path& session_dir, const std::vector<StageSpec>& built,
                       const RunRequest& request,
                       const std::function<void(const StageEvent&)>& on_event) {
  Session session = Session::open(session_dir);
  const fs::path& root = session.root();
  std::vector<StageSpec> plan = plan_run(session, built, request);
  for (const auto& [name, why] : stages_left_alone(session, built)) {
    log::info("{}: {}", name, why);
  }
  RunResult result;
  // Folder -> the stage of this invocation that rewrote it: its readers must rerun.
  std::map<std::string, std::string> rewritten;

  for (std::size_t i = 0; i < plan.size(); ++i) {
    const StageSpec& stage = plan[i];
    StageEvent event;
    event.index = i + 1;
    event.count = plan.size();
    event.stage = stage.name;
    event.log_file = session.logs_dir() / (stage.name + ".log");
    auto emit = [&](StageEvent::Kind kind) {
      event.kind = kind;
      if (on_event) on_event(event);
    };

    // synth itself refuses to overwrite a capture/ it did not make (its .synthetic marker).
    StageFingerprint fp = fingerprint(session, stage);
    std::string upstream;
    std::string reason;
    if (request.force) {
      reason = "forced";
    } else if (reads_any(stage.inputs, rewritten, &upstream)) {
      reason = fmt::format("upstream stage {} ran", upstream);
    } else {
      reason = staleness(root, stage, fp);
    }
    if (reason.empty()) {
      event.reason = "up to date";
      emit(StageEvent::Kind::kSkipped);
      result.skipped.push_back(stage.name);
      continue;
    }

    // Remove the record first: if the stage crashes, the next run must not trust its outputs.
    fs::path record_file = record_path(root, stage);
    std::error_code ec;
    fs::remove(record_file, ec);
    if (ec) throw IoError(fmt::format("cannot remove {}: {}", record_file.string(), ec.message()));

    // A run that was killed may have left its writers' temp files; they are not outputs.
    for (const auto& out : stage.outputs) {
      const int stale = remove_temp_files(root / out);
      if (stale > 0) log::info("{}: removed {} temp file(s) of an interrupted run", out, stale);
    }

    event.reason = reason;
    emit(StageEvent::Kind::kStarted);
    log::Timer timer;
    // A per-frame stage runs as its jobs, one after the other (each uses every thread).
    const std::vector<Job> jobs =
        stage_jobs(stage, stage.per_frame() ? session_capture(session) : CaptureIndex{},
                   request.frames_per_job, request.branch_jobs);
    int code = 0;
    event.usage = {};
    for (const Job& job : jobs) {
      ProcessUsage used;
      code = run_stage_process(stage, root, request.threads, request.verbose, job.arguments(),
                               &used);
      event.usage.cpu_seconds += used.cpu_seconds;
      event.usage.peak_rss_bytes = std::max(event.usage.peak_rss_bytes, used.peak_rss_bytes);
      if (code != 0) {
        event.log_file = session.logs_dir() / job.log_name();
        event.reason = fmt::format("job {} failed", job.name());
        break;
      }
    }
    event.jobs = jobs.size();
    event.seconds = timer.seconds();
    if (code != 0) {
      event.exit_code = code;
      emit(StageEvent::Kind::kFailed);
      result.exit_code = code;
      result.failed_stage = stage.name;
      result.log_file = event.log_file;
      return result;
    }

    CompletionRecord record;
    record.stage = stage.name;
    record.fingerprint = std::move(fp);
    record.outputs = hash_folders(root, stage.outputs);
    record.output_bytes = folder_bytes(root, stage.outputs);
    record.finished = log::local_time();
    record.seconds = event.seconds;
    record.cpu_seconds = event.usage.cpu_seconds;
    record.peak_rss_bytes = event.usage.peak_rss_bytes;
    write_record(record_file, record);  // last: only now is the stage complete

    for (const auto& out : stage.outputs) rewritten[out] = stage.name;
    emit(StageEvent::Kind::kFinished);
    result.ran.push_back(stage.name);
  }
  return result;
}

const char* state_name(StageStatus::State state) {
  switch (state) {
    case StageStatus::State::kDone:
      return "done";
    case StageStatus::State::kChanged:
      return "changed";
    case StageStatus::State::kNotRun:
      return "not run";
    case StageStatus::State::kIncomplete:
      return "failed or incomplete";
    case StageStatus::State::kNotUsed:
      return "not used";
    case StageStatus::State::kImported:
      return "imported";
  }
  return "";
}

namespace {

// Entries of the `warnings` list in the stage's <first output>/report.json (0 without one).
std::size_t report_warnings(const fs::path& session_root, const StageSpec& stage) {
  const fs::path report = session_root / stage.outputs.front() / "report.json";
  std::error_code ec;
  if (!fs::is_regular_file(report, ec)) return 0;
  const nlohmann::json j = nlohmann::json::parse(read_file(report), nullptr, false);
  if (!j.is_object() || !j.contains("warnings") || !j["warnings"].is_array()) return 0;
  return j["warnings"].size();
}

}  // namespace

std::vector<StageStatus> session_status(const fs::path& session_dir,
                                        const std::vector<StageSpec>& built) {
  Session session = Session::open(session_dir);
  const fs::path& root = session.root();
  bool uses_synth = session_uses_synth(session);
  const std::map<std::string, std::string> alone = stages_left_alone(session, built);
  // Folder -> the stage that would rewrite it on the next run.
  std::map<std::string, std::string> pending;
  std::vector<StageStatus> table;
  for (const auto& stage :
       with_oracle_variants(root, built, built, configured_oracle(session, built))) {
    StageStatus s;
    s.stage = stage.name;
    s.output_bytes = folder_bytes(root, stage.outputs);
    if (stage.name == "synth" && !uses_synth) {
      s.state = StageStatus::State::kNotUsed;
      s.detail = "no stages.synth section: capture/ is a real capture";
      table.push_back(std::move(s));
      continue;
    }
    if (auto a = alone.find(stage.name); a != alone.end()) {
      s.state = is_imported(root, stage) ? StageStatus::State::kImported
                                         : StageStatus::State::kNotUsed;
      s.detail = a->second;
      table.push_back(std::move(s));
      continue;
    }
    s.record = read_record(record_path(root, stage));
    if (!s.record) {
      std::error_code ec;
      fs::path log_file = session.logs_dir() / (stage.name + ".log");
      if (s.output_bytes > 0 || fs::exists(log_file, ec)) {
        s.state = StageStatus::State::kIncomplete;
        s.detail =
            fmt::format("no completion record: the last run failed or was interrupted (see {})",
                        log_file.string());
      } else {
        s.state = StageStatus::State::kNotRun;
      }
    } else {
      std::string reason = staleness(root, stage, fingerprint(session, stage));
      std::string upstream;
      if (reason.empty() && reads_any(stage.inputs, pending, &upstream)) {
        reason = fmt::format("upstream stage {} will rerun", upstream);
      }
      s.state = reason.empty() ? StageStatus::State::kDone : StageStatus::State::kChanged;
      s.detail = reason;
    }
    s.warnings = report_warnings(root, stage);
    if (s.warnings > 0) {
      s.detail += fmt::format("{}{} warning(s): see {}/report.json", s.detail.empty() ? "" : "; ",
                              s.warnings, stage.outputs.front());
    }
    if (s.state != StageStatus::State::kDone) {
      for (const auto& out : stage.outputs) pending[out] = stage.name;
    }
    table.push_back(std::move(s));
  }
  return table;
}

}  // namespace fourd::driver
