#pragma once
// A stage's output folder replaced as a whole: outputs are written into a fresh folder beside
// the final one, which replaces the final folder only when everything is written. A failure
// before commit() leaves the previous outputs as they were and removes the partial folder.
#include <filesystem>

namespace fourd {

class StagedFolder {
 public:
  // Creates the hidden ".<target>.staging.tmp" beside the target, removing what a killed run
  // left there first (the name is fixed, so the next run finds it).
  explicit StagedFolder(std::filesystem::path target);
  ~StagedFolder();
  StagedFolder(const StagedFolder&) = delete;
  StagedFolder& operator=(const StagedFolder&) = delete;

  const std::filesystem::path& path() const { return staging_; }
  // Moves the previous folder aside, renames the staging folder onto the target, then removes
  // the previous folder. Throws IoError naming the folder on failure.
  void commit();

 private:
  std::filesystem::path target_;
  std::filesystem::path staging_;
  bool committed_ = false;
};

}  // namespace fourd
