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

// Removes a folder and everything in it as one step as far as readers can tell: it is first
// renamed to the hidden ".<name>.removing.tmp" beside it (what a killed run left under that
// name is removed first), then deleted. A kill mid-way never leaves a half-emptied folder under
// the real name. Nothing happens when the folder does not exist; throws IoError naming it when
// it cannot be moved or removed.
void remove_folder(const std::filesystem::path& dir);

}  // namespace fourd
