#include "pipeline/core/files.h"

#include <fcntl.h>
#include <unistd.h>
#include <xxhash.h>

#include <atomic>
#include <cctype>
#include <cstdio>
#include <fmt/format.h>
#include <vector>

#include "pipeline/core/error.h"

namespace fourd {
namespace {

void fsync_path(const fs::path& path) {
  int fd = ::open(path.c_str(), O_RDONLY);
  if (fd >= 0) {
    ::fsync(fd);
    ::close(fd);
  }
}

}  // namespace

fs::path temp_path_for(const fs::path& path) {
  static std::atomic<unsigned> counter{0};
  // Keep the extension last so writers that dispatch on it (OpenCV, OIIO) still work.
  return path.parent_path() / fmt::format(".{}.tmp{}-{}{}", path.stem().string(), ::getpid(),
                                          counter++, path.extension().string());
}

bool is_temp_file(const fs::path& path) {
  // ".<stem>.tmp<pid>-<n><ext>": the stem may itself contain dots, the pid and n are digits.
  const std::string name = path.filename().string();
  if (name.size() < 2 || name[0] != '.') return false;
  for (std::size_t at = name.find(".tmp", 1); at != std::string::npos;
       at = name.find(".tmp", at + 1)) {
    std::size_t i = at + 4;
    const std::size_t pid_start = i;
    while (i < name.size() && std::isdigit(static_cast<unsigned char>(name[i]))) ++i;
    if (i == pid_start || i >= name.size() || name[i] != '-') continue;
    const std::size_t n_start = ++i;
    while (i < name.size() && std::isdigit(static_cast<unsigned char>(name[i]))) ++i;
    if (i == n_start) continue;
    if (i == name.size() || name[i] == '.') return true;
  }
  return false;
}

int remove_temp_files(const fs::path& dir) {
  std::error_code ec;
  if (!fs::is_directory(dir, ec)) return 0;
  std::vector<fs::path> stale;
  for (fs::recursive_directory_iterator it(dir, ec), end; !ec && it != end; it.increment(ec)) {
    std::error_code fec;
    if (it->is_regular_file(fec) && is_temp_file(it->path())) stale.push_back(it->path());
  }
  if (ec) throw IoError(fmt::format("cannot list {}: {}", dir.string(), ec.message()));
  for (const fs::path& p : stale) {
    if (!fs::remove(p, ec) && ec) {
      throw IoError(fmt::format("cannot remove {}: {}", p.string(), ec.message()));
    }
  }
  return static_cast<int>(stale.size());
}

void require_free_space(const fs::path& dir, std::uintmax_t bytes, std::string_view what) {
  fs::path existing = fs::absolute(dir);
  std::error_code ec;
  while (!fs::exists(existing, ec) && existing.has_parent_path() &&
         existing != existing.parent_path()) {
    existing = existing.parent_path();
  }
  const fs::space_info space = fs::space(existing, ec);
  if (ec) {
    throw IoError(fmt::format("cannot query the free space of {}: {}", existing.string(),
                              ec.message()));
  }
  if (space.available < bytes) {
    constexpr double kMiB = 1024.0 * 1024.0;
    throw IoError(fmt::format(
        "not enough disk space for {} in {}: needs about {:.0f} MiB, {:.0f} MiB free", what,
        dir.string(), bytes / kMiB, space.available / kMiB));
  }
}

void commit_temp_file(const fs::path& temp, const fs::path& path) {
  fsync_path(temp);
  std::error_code ec;
  fs::rename(temp, path, ec);
  if (ec) {
    fs::remove(temp, ec);
    throw IoError(fmt::format("cannot move {} onto {}: {}", temp.string(), path.string(),
                              ec.message()));
  }
}

AtomicFile::AtomicFile(fs::path path, bool binary) : path_(std::move(path)) {
  if (!path_.parent_path().empty()) ensure_directory(path_.parent_path());
  temp_ = temp_path_for(path_);
  out_.open(temp_, binary ? std::ios::binary | std::ios::trunc : std::ios::trunc);
  if (!out_) throw IoError(fmt::format("cannot open {} for writing", temp_.string()));
}

AtomicFile::~AtomicFile() {
  if (!committed_) {
    out_.close();
    std::error_code ec;
    fs::remove(temp_, ec);
  }
}

void AtomicFile::commit() {
  out_.flush();
  bool ok = static_cast<bool>(out_);
  out_.close();
  if (!ok) {
    std::error_code ec;
    fs::remove(temp_, ec);
    committed_ = true;
    throw IoError(fmt::format("writing {} failed (disk full?)", path_.string()));
  }
  committed_ = true;
  commit_temp_file(temp_, path_);
}

void write_file_atomic(const fs::path& path, std::string_view bytes) {
  AtomicFile file(path);
  file.stream().write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
  file.commit();
}

std::string read_file(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) {
    if (!fs::exists(path)) throw IoError(fmt::format("{}: file does not exist", path.string()));
    throw IoError(fmt::format("{}: cannot open for reading", path.string()));
  }
  std::error_code ec;
  const auto size = fs::file_size(path, ec);
  if (ec) throw IoError(fmt::format("{}: cannot read size: {}", path.string(), ec.message()));
  std::string bytes(size, '\0');
  in.read(bytes.data(), static_cast<std::streamsize>(size));
  if (static_cast<std::size_t>(in.gcount()) != size) {
    throw IoError(fmt::format("{}: read error (got {} of {} bytes)", path.string(), in.gcount(), size));
  }
  return bytes;
}

void ensure_directory(const fs::path& dir) {
  std::error_code ec;
  fs::create_directories(dir, ec);
  if (ec) throw IoError(fmt::format("cannot create directory {}: {}", dir.string(), ec.message()));
}

std::uint64_t hash_bytes(std::string_view bytes, std::uint64_t seed) {
  return XXH3_64bits_withSeed(bytes.data(), bytes.size(), seed);
}

std::uint64_t hash_file(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw IoError(fmt::format("{}: cannot open for hashing", path.string()));
  XXH3_state_t* state = XXH3_createState();
  XXH3_64bits_reset(state);
  std::vector<char> buffer(1 << 20);
  while (in) {
    in.read(buffer.data(), static_cast<std::streamsize>(buffer.size()));
    XXH3_64bits_update(state, buffer.data(), static_cast<size_t>(in.gcount()));
  }
  std::uint64_t h = XXH3_64bits_digest(state);
  XXH3_freeState(state);
  return h;
}

std::string hash_hex(std::uint64_t h) { return fmt::format("{:016x}", h); }

}  // namespace fourd
