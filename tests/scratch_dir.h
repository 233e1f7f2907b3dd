#pragma once
// Scratch folders for tests that write files: <tmp>/fourd_test_<pid>/<name>, created empty.
// The process's whole fourd_test_<pid> folder is removed when the process exits normally, so a
// test run leaves nothing behind in the temp folder.
#include <unistd.h>

#include <cstdlib>
#include <filesystem>
#include <string>

namespace fourd::test {

inline const std::filesystem::path& scratch_root() {
  static const std::filesystem::path root =
      std::filesystem::temp_directory_path() / ("fourd_test_" + std::to_string(::getpid()));
  // Registered after `root` is built, so it runs before `root` is destroyed.
  static const bool removed_at_exit = [] {
    return std::atexit([] {
      std::error_code ec;
      std::filesystem::remove_all(root, ec);
    }) == 0;
  }();
  (void)removed_at_exit;
  return root;
}

inline std::filesystem::path scratch_dir(const std::string& name) {
  const std::filesystem::path d = scratch_root() / name;
  std::filesystem::remove_all(d);
  std::filesystem::create_directories(d);
  return d;
}

}  // namespace fourd::test
