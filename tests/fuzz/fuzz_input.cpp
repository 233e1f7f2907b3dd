#include "tests/fuzz/fuzz_input.h"

#include <unistd.h>

#include <cstdlib>
#include <cstring>
#include <fstream>

#include "pipeline/core/binary_format.h"
#include "pipeline/core/files.h"

namespace fourd::fuzz {
namespace {

void remove_scratch() {
  std::error_code ec;
  std::filesystem::remove_all(scratch_dir(), ec);
}

std::map<std::string, Target>& registry() {
  static std::map<std::string, Target> map;
  return map;
}

}  // namespace

const std::map<std::string, Target>& targets() { return registry(); }

Registration::Registration(const char* name, Target target) { registry()[name] = target; }

const std::filesystem::path& scratch_dir() {
  static const std::filesystem::path dir = [] {
    auto d = std::filesystem::temp_directory_path() / ("fourd-fuzz-" + std::to_string(getpid()));
    std::filesystem::create_directories(d);
    std::atexit(remove_scratch);
    return d;
  }();
  return dir;
}

std::filesystem::path write_input(const std::string& name, std::string_view bytes) {
  const std::filesystem::path path = scratch_dir() / name;
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  out.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
  if (!out.flush()) std::abort();  // the harness itself failed, not the code under test
  return path;
}

std::vector<std::string_view> split_parts(std::string_view text, std::size_t count) {
  constexpr std::string_view kMarker = "--8<--";
  std::vector<std::string_view> parts(count);
  std::size_t part = 0;
  std::size_t start = 0;
  while (part < count) {
    std::size_t at = text.find(kMarker, start);
    while (at != std::string_view::npos && at != 0 && text[at - 1] != '\n') {
      at = text.find(kMarker, at + 1);
    }
    if (at == std::string_view::npos) {
      parts[part] = text.substr(start);
      break;
    }
    parts[part++] = text.substr(start, at - start);
    const std::size_t eol = text.find('\n', at);
    if (eol == std::string_view::npos) break;
    start = eol + 1;
  }
  return parts;
}

std::string restamp_binary_header(std::string_view file) {
  std::string bytes(file);
  if (bytes.size() < kBinaryHeaderSize) return bytes;
  const std::uint64_t payload_size = bytes.size() - kBinaryHeaderSize;
  const std::uint64_t checksum =
      hash_bytes(std::string_view(bytes).substr(kBinaryHeaderSize));
  std::memcpy(bytes.data() + 16, &payload_size, sizeof(payload_size));
  std::memcpy(bytes.data() + 24, &checksum, sizeof(checksum));
  return bytes;
}

}  // namespace fourd::fuzz
