#pragma once
// File helpers: atomic writes (temp file + rename, so a crash never leaves half a file that a
// later stage trusts), whole-file reads with clear errors, and content hashes.
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <string>
#include <string_view>

namespace fourd {

namespace fs = std::filesystem;

// Writes to "<path>.tmp-<pid>" and renames onto `path` in commit(). If the object is destroyed
// without commit() (an exception, an early return) the temp file is removed and `path` is left
// as it was.
class AtomicFile {
 public:
  explicit AtomicFile(fs::path path, bool binary = true);
  ~AtomicFile();
  AtomicFile(const AtomicFile&) = delete;
  AtomicFile& operator=(const AtomicFile&) = delete;

  std::ofstream& stream() { return out_; }
  const fs::path& temp_path() const { return temp_; }
  // Flushes, checks the stream, fsyncs and renames. Throws IoError on failure.
  void commit();

 private:
  fs::path path_;
  fs::path temp_;
  std::ofstream out_;
  bool committed_ = false;
};

// Temp path beside `path` for writers that need a file name (OpenCV, OpenImageIO): write to
// it, then call commit_temp_file(temp, path).
fs::path temp_path_for(const fs::path& path);
void commit_temp_file(const fs::path& temp, const fs::path& path);
// Whether `path` names a temp file of the writers above (".<stem>.tmp<pid>-<n><ext>").
bool is_temp_file(const fs::path& path);
// Removes the temp files a killed writer left anywhere under `dir` (nothing if `dir` does not
// exist); returns how many. Only for folders no other process is writing to.
int remove_temp_files(const fs::path& dir);

void write_file_atomic(const fs::path& path, std::string_view bytes);
std::string read_file(const fs::path& path);  // throws IoError naming the file

// Checks, before a stage writes large outputs, that the file system holding `dir` (or its
// nearest existing parent) has `bytes` free. Throws IoError naming the folder, what needs the
// space, how much it needs and how much is free.
void require_free_space(const fs::path& dir, std::uintmax_t bytes, std::string_view what);

// Creates the directory (and parents); throws IoError naming it on failure.
void ensure_directory(const fs::path& dir);

// 64-bit content hashes (XXH3). hash_file streams the file.
std::uint64_t hash_bytes(std::string_view bytes, std::uint64_t seed = 0);
std::uint64_t hash_file(const fs::path& path);
std::string hash_hex(std::uint64_t h);

}  // namespace fourd
