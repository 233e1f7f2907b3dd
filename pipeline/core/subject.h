#pragma once
// The size of the filmed subject, one per session (docs/design.md, "Subjects of any size").
//
// Reconstruct measures it on the visual hull and writes reconstruct/subject.json
// (stages/reconstruct/subject.h); every stage after it scales its subject-relative lengths
// (config.h, Length) by the same factor, read with stage_subject(). When reconstruct/ was
// imported (meshes from another tool) there is no subject.json and the subject is measured on
// the stage's own input meshes instead, with the same rule: the median over a few frames of the
// largest side of the bounding box, factor = size / kReferenceSubjectSize rounded to
// 10^(k / 20), so that subjects near the reference get exactly the tuned defaults.
#include <filesystem>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "pipeline/core/mesh.h"
#include "pipeline/core/session.h"

namespace fourd {

// File name of the subject record in reconstruct/.
inline constexpr const char* kSubjectFile = "subject.json";
// Steps per decade of the factor's rounding when nothing else is configured.
inline constexpr int kSubjectScaleSteps = 20;

// size / kReferenceSubjectSize, rounded to 10^(k / steps_per_decade) (not when <= 0).
double subject_scale_factor(double size, int steps_per_decade = kSubjectScaleSteps);

struct Subject {
  double size = 0;    // largest extent [m]
  double height = 0;  // vertical (z) extent [m]
  double factor = 1;  // of the reference subject's size
  std::string source; // where it came from, for the log and options.yaml
};

// <dir>/subject.json as reconstruct writes it; nullopt when there is none. Throws InputError
// naming the file when it is there but unreadable or implausible.
std::optional<Subject> read_subject(const std::filesystem::path& dir);

// The subject measured on `meshes` (the median of their boxes' largest and vertical sides).
// Throws InputError when no mesh has a vertex.
Subject measure_subject(const std::vector<Mesh>& meshes, const std::string& what);

// The subject a stage after reconstruct scales its lengths to: <input_dir>/subject.json, else
// the session's reconstruct/subject.json, else what `measure()` gives (e.g. measure_subject on
// a few of the stage's input meshes, spread through the session).
Subject stage_subject(const Session& session, const std::filesystem::path& input_dir,
                      const std::function<Subject()>& measure);

// Logs the subject a stage scaled `scaled` lengths to.
void log_subject(const std::string& stage, const Subject& subject, std::size_t scaled);

// The options of `stage` from the session's layers, with every subject-relative length they
// leave unset scaled to `subject` (config.h, scale_unset_lengths). Logs the subject and the
// count of scaled lengths; returns the scaled keys. With `set_keys`, the keys the layers set
// are added to it.
template <class T>
std::vector<std::string> subject_stage_options(const Session& session, const std::string& stage,
                                               const Subject& subject, T& opts,
                                               SetKeys* set_keys = nullptr) {
  SetKeys keys;
  session.stage_options(stage, opts, &keys);
  std::vector<std::string> scaled =
      scale_unset_lengths(opts, subject.factor, keys, "stages." + stage);
  log_subject(stage, subject, scaled.size());
  if (set_keys) set_keys->insert(keys.begin(), keys.end());
  return scaled;
}

// The first line of a stage's options.yaml: the subject and how many lengths it scaled.
std::string subject_comment(const Subject& subject, std::size_t scaled);

// Indices of `count` items spread evenly through `n` (the middle of each of `count` equal
// parts), fewer when n < count.
std::vector<std::size_t> spread_indices(std::size_t n, std::size_t count);

}  // namespace fourd
