#include "pipeline/core/binary_format.h"

#include <fmt/format.h>

#include <algorithm>
#include <cctype>
#include <limits>

#include "pipeline/core/error.h"
#include "pipeline/core/files.h"

namespace fourd {
namespace {

struct Header {
  char magic[8];
  std::uint32_t version;
  std::uint32_t byte_order;
  std::uint64_t payload_size;
  std::uint64_t checksum;
};
static_assert(sizeof(Header) == kBinaryHeaderSize, "the header is 32 bytes without padding");

std::string printable(std::string_view bytes) {
  std::string text;
  for (char c : bytes) {
    if (c == '\0') continue;
    text += std::isprint(static_cast<unsigned char>(c)) ? c : '?';
  }
  return text;
}

}  // namespace

std::string FileMagic::text() const { return printable(bytes()); }

void BinaryWriter::write_string(std::string_view text) {
  write<std::uint64_t>(text.size());
  write_bytes(text.data(), text.size());
}

void BinaryWriter::write_bytes(const void* data, std::size_t size) {
  if (size > 0) payload_.append(static_cast<const char*>(data), size);
}

namespace {

Header make_header(const FileMagic& magic, std::uint32_t version, std::string_view payload) {
  Header header{};
  std::memcpy(header.magic, magic.bytes().data(), sizeof(header.magic));
  header.version = version;
  header.byte_order = kByteOrderMarker;
  header.payload_size = payload.size();
  header.checksum = hash_bytes(payload);
  return header;
}

}  // namespace

std::string BinaryWriter::file_bytes(const FileMagic& magic, std::uint32_t version) const {
  const Header header = make_header(magic, version, payload_);
  std::string bytes(reinterpret_cast<const char*>(&header), sizeof(header));
  bytes += payload_;
  return bytes;
}

void BinaryWriter::save(const std::filesystem::path& path, const FileMagic& magic,
                        std::uint32_t version) const {
  const Header header = make_header(magic, version, payload_);
  AtomicFile file(path);
  file.stream().write(reinterpret_cast<const char*>(&header), sizeof(header));
  file.stream().write(payload_.data(), static_cast<std::streamsize>(payload_.size()));
  file.commit();
}

BinaryReader::BinaryReader(std::filesystem::path path, std::string bytes, std::size_t offset,
                           std::uint32_t version)
    : path_(std::move(path)), bytes_(std::move(bytes)), offset_(offset), version_(version) {}

BinaryReader BinaryReader::open(const std::filesystem::path& path, const FileMagic& magic,
                                std::span<const std::uint32_t> supported_versions) {
  return from_bytes(path, read_file(path), magic, supported_versions);
}

BinaryReader BinaryReader::from_bytes(const std::filesystem::path& path, std::string bytes,
                                      const FileMagic& magic,
                                      std::span<const std::uint32_t> supported_versions) {
  const std::string name = path.string();
  if (bytes.size() < sizeof(Header)) {
    throw InputError(fmt::format("{}: truncated: {} bytes, shorter than the {}-byte header", name,
                                 bytes.size(), sizeof(Header)));
  }
  Header header;
  std::memcpy(&header, bytes.data(), sizeof(header));
  if (magic.bytes() != std::string_view(header.magic, sizeof(header.magic))) {
    throw InputError(fmt::format("{}: not a {} file (its magic is \"{}\")", name, magic.text(),
                                 printable({header.magic, sizeof(header.magic)})));
  }
  if (header.byte_order != kByteOrderMarker) {
    throw InputError(fmt::format(
        "{}: byte-order marker is {:#010x}, not {:#010x}: the file was written on a machine "
        "with the other endianness (or is corrupt)",
        name, header.byte_order, kByteOrderMarker));
  }
  if (std::find(supported_versions.begin(), supported_versions.end(), header.version) ==
      supported_versions.end()) {
    throw InputError(fmt::format("{}: {} format version {} is not supported (this build reads {})",
                                 name, magic.text(), header.version,
                                 fmt::join(supported_versions, ", ")));
  }
  const std::size_t available = bytes.size() - sizeof(Header);
  if (header.payload_size > available) {
    throw InputError(fmt::format("{}: truncated: header announces {} payload bytes, file has {}",
                                 name, header.payload_size, available));
  }
  if (header.payload_size < available) {
    throw InputError(fmt::format("{}: {} unexpected bytes after the {}-byte payload", name,
                                 available - header.payload_size, header.payload_size));
  }
  std::string_view payload(bytes.data() + sizeof(Header), available);
  if (hash_bytes(payload) != header.checksum) {
    throw InputError(fmt::format("{}: checksum mismatch: the file is corrupt", name));
  }
  return BinaryReader(path, std::move(bytes), sizeof(Header), header.version);
}

void BinaryReader::expect_end() const {
  if (!at_end()) {
    throw InputError(
        fmt::format("{}: {} unread bytes at the end of the payload", path_.string(), remaining()));
  }
}

void BinaryReader::read_bytes(void* out, std::size_t size) {
  if (size > remaining()) throw_truncated(size, "value");
  if (size > 0) std::memcpy(out, bytes_.data() + offset_, size);
  offset_ += size;
}

std::string BinaryReader::read_string() {
  std::size_t size = read_count(1, "string");
  std::string text(bytes_.data() + offset_, size);
  offset_ += size;
  return text;
}

std::size_t BinaryReader::read_count(std::size_t element_size, const char* what) {
  auto count = read<std::uint64_t>();
  // Divide rather than multiply so a huge count cannot overflow and pass the check.
  if (element_size > 0 && count > remaining() / element_size) {
    throw InputError(fmt::format(
        "{}: truncated: {} of {} elements of {} bytes at payload offset {} exceeds the {} bytes "
        "left",
        path_.string(), what, count, element_size, offset_ - sizeof(Header), remaining()));
  }
  return static_cast<std::size_t>(count);
}

void BinaryReader::check_matrix_shape(std::uint64_t rows, std::uint64_t cols, int fixed_rows,
                                      int fixed_cols, std::size_t scalar_size) {
  const std::string name = path_.string();
  if ((fixed_rows != Eigen::Dynamic && rows != static_cast<std::uint64_t>(fixed_rows)) ||
      (fixed_cols != Eigen::Dynamic && cols != static_cast<std::uint64_t>(fixed_cols))) {
    throw InputError(fmt::format("{}: matrix of {} x {} where {} x {} was expected", name, rows,
                                 cols, fixed_rows, fixed_cols));
  }
  // Each dimension must fit Eigen::Index even when the other is 0 (a 0 x 2^63 matrix holds no
  // bytes but is not a size Eigen accepts).
  const std::uint64_t max_dimension = std::numeric_limits<Eigen::Index>::max();
  const std::uint64_t max_elements = remaining() / scalar_size;
  if (rows > max_dimension || cols > max_dimension || (rows != 0 && cols > max_elements / rows)) {
    throw InputError(fmt::format(
        "{}: truncated: matrix of {} x {} at payload offset {} exceeds the {} bytes left", name,
        rows, cols, offset_ - sizeof(Header), remaining()));
  }
}

void BinaryReader::throw_truncated(std::size_t needed, const char* what) const {
  throw InputError(fmt::format("{}: truncated: {} of {} bytes at payload offset {}, {} left",
                               path_.string(), what, needed, offset_ - sizeof(Header),
                               remaining()));
}

}  // namespace fourd
