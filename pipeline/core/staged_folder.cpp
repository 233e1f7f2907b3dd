#include "pipeline/core/staged_folder.h"

#include <fmt/format.h>

#include <system_error>

#include "pipeline/core/error.h"
#include "pipeline/core/files.h"

namespace fourd {

namespace {

std::filesystem::path sibling(const std::filesystem::path& target, const char* what) {
  return target.parent_path() / fmt::format(".{}.{}.tmp", target.filename().string(), what);
}

}  // namespace

StagedFolder::StagedFolder(std::filesystem::path target)
    : target_(std::move(target)), staging_(sibling(target_, "staging")) {
  std::error_code ec;
  std::filesystem::remove_all(staging_, ec);
  ensure_directory(staging_);
}

StagedFolder::~StagedFolder() {
  if (committed_) return;
  std::error_code ec;
  std::filesystem::remove_all(staging_, ec);
}

void StagedFolder::commit() {
  std::error_code ec;
  const std::filesystem::path previous = sibling(target_, "previous");
  std::filesystem::remove_all(previous, ec);
  if (std::filesystem::exists(target_)) {
    std::filesystem::rename(target_, previous, ec);
    if (ec) {
      throw IoError(fmt::format("cannot move {} aside: {}", target_.string(), ec.message()));
    }
  }
  std::filesystem::rename(staging_, target_, ec);
  if (ec) {
    std::error_code back;
    if (std::filesystem::exists(previous)) std::filesystem::rename(previous, target_, back);
    throw IoError(fmt::format("cannot replace {}: {}", target_.string(), ec.message()));
  }
  committed_ = true;
  std::filesystem::remove_all(previous, ec);
}

void remove_folder(const std::filesystem::path& dir) {
  const std::filesystem::path doomed = sibling(dir, "removing");
  std::error_code ec;
  std::filesystem::remove_all(doomed, ec);
  if (ec) throw IoError(fmt::format("cannot remove {}: {}", doomed.string(), ec.message()));
  if (!std::filesystem::exists(dir, ec)) return;
  std::filesystem::rename(dir, doomed, ec);
  if (ec) throw IoError(fmt::format("cannot clear {}: {}", dir.string(), ec.message()));
  std::filesystem::remove_all(doomed, ec);
  if (ec) throw IoError(fmt::format("cannot remove {}: {}", doomed.string(), ec.message()));
}

}  // namespace fourd
