#pragma once
// A small versioned container for binary files passed between stages and for the runtime
// asset. Layout (native byte order, 32-byte header):
//   char[8]  magic            one per file kind, e.g. "FOURDTW" padded with '\0'
//   uint32   format version   the reader refuses versions it does not list
//   uint32   0x01020304       byte-order marker: refuses files from the other endianness
//   uint64   payload size     bytes after the header
//   uint64   XXH3 checksum    of the payload, catches corruption and partial copies
//   payload                  whatever BinaryWriter appended, read back in the same order
// Arrays, strings and dynamic matrices are stored with a uint64 count in front. Reads are
// bounds-checked: a bad file raises InputError naming the file, never reads past the end.
#include <Eigen/Core>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <initializer_list>
#include <span>
#include <string>
#include <string_view>
#include <type_traits>
#include <vector>

namespace fourd {

// The 8-byte tag of a file kind. Built from a literal of at most 8 characters (checked at
// compile time), padded with '\0': `constexpr FileMagic kTimewarpMagic("FOURDTW");`
class FileMagic {
 public:
  template <std::size_t N>
  consteval FileMagic(const char (&text)[N]) {  // NOLINT: implicit from a literal on purpose
    static_assert(N >= 2 && N <= 9, "a file magic has 1 to 8 characters");
    for (std::size_t i = 0; i + 1 < N; ++i) bytes_[i] = text[i];
  }
  std::string_view bytes() const { return {bytes_, sizeof(bytes_)}; }
  // Printable form for messages ("FOURDTW").
  std::string text() const;

 private:
  char bytes_[8] = {};
};

inline constexpr std::uint32_t kByteOrderMarker = 0x01020304u;
inline constexpr std::size_t kBinaryHeaderSize = 32;

namespace binary_detail {

// Types stored as their raw bytes: trivially copyable values and fixed-size Eigen matrices
// (which are not trivially copyable in Eigen 3.4 only because they declare a copy
// constructor, but are plain arrays of scalars in memory).
template <class T>
struct IsFixedEigen : std::false_type {};
template <class S, int R, int C, int O, int MR, int MC>
struct IsFixedEigen<Eigen::Matrix<S, R, C, O, MR, MC>>
    : std::bool_constant<R != Eigen::Dynamic && C != Eigen::Dynamic && std::is_arithmetic_v<S> &&
                         sizeof(Eigen::Matrix<S, R, C, O, MR, MC>) == sizeof(S) * R * C> {};

template <class T>
inline constexpr bool kIsBlittable =
    (std::is_trivially_copyable_v<T> && !std::is_pointer_v<T>) || IsFixedEigen<T>::value;

template <class T>
struct IsDynamicEigen : std::false_type {};
template <class S, int R, int C, int O, int MR, int MC>
struct IsDynamicEigen<Eigen::Matrix<S, R, C, O, MR, MC>> {
  static constexpr bool value =
      std::is_arithmetic_v<S> && (R == Eigen::Dynamic || C == Eigen::Dynamic);
};

}  // namespace binary_detail

// Appends values to an in-memory payload, then saves it behind a header in one atomic write.
class BinaryWriter {
 public:
  // One plain value (int, float, POD struct, Vec3f, Matrix4d...).
  template <class T>
  void write(const T& value) {
    static_assert(binary_detail::kIsBlittable<T>, "write() takes plain values; see below");
    write_bytes(&value, sizeof(T));
  }
  // A count (uint64) followed by the elements.
  template <class T>
  void write_span(std::span<const T> values) {
    static_assert(binary_detail::kIsBlittable<T>, "write_span() takes plain values");
    write<std::uint64_t>(values.size());
    write_bytes(values.data(), values.size_bytes());
  }
  template <class T>
  void write_vector(const std::vector<T>& values) {
    write_span(std::span<const T>(values));
  }
  void write_string(std::string_view text);
  // A dynamic-size Eigen matrix or vector: rows, cols (uint64) and the column-major data.
  template <class M>
  void write_matrix(const M& matrix) {
    static_assert(binary_detail::IsDynamicEigen<M>::value, "write_matrix() takes MatrixX*");
    write<std::uint64_t>(static_cast<std::uint64_t>(matrix.rows()));
    write<std::uint64_t>(static_cast<std::uint64_t>(matrix.cols()));
    write_bytes(matrix.data(), sizeof(typename M::Scalar) * matrix.size());
  }
  // Raw bytes without a count (the reader must know the size).
  void write_bytes(const void* data, std::size_t size);

  const std::string& payload() const { return payload_; }
  std::size_t size() const { return payload_.size(); }
  void reserve(std::size_t bytes) { payload_.reserve(bytes); }

  // Header + payload, the bytes save() writes (e.g. to compress them first).
  std::string file_bytes(const FileMagic& magic, std::uint32_t version) const;
  // Header + payload, atomically. Throws IoError when the file cannot be written.
  void save(const std::filesystem::path& path, const FileMagic& magic, std::uint32_t version) const;

 private:
  std::string payload_;
};

// Reads a whole container, validates its header and checksum, then hands out values in the
// order they were written.
class BinaryReader {
 public:
  // Throws IoError if the file cannot be read, InputError naming the file and the problem for
  // a wrong magic, a version not in `supported_versions`, the other byte order, a truncated
  // file or a checksum mismatch.
  static BinaryReader open(const std::filesystem::path& path, const FileMagic& magic,
                           std::span<const std::uint32_t> supported_versions);
  static BinaryReader open(const std::filesystem::path& path, const FileMagic& magic,
                           std::initializer_list<std::uint32_t> supported_versions) {
    return open(
        path, magic,
        std::span<const std::uint32_t>(supported_versions.begin(), supported_versions.size()));
  }

  // The same from a file's bytes already in memory (e.g. inflated); `path` names it in errors.
  static BinaryReader from_bytes(const std::filesystem::path& path, std::string bytes,
                                 const FileMagic& magic,
                                 std::span<const std::uint32_t> supported_versions);

  std::uint32_t version() const { return version_; }
  const std::filesystem::path& path() const { return path_; }
  std::size_t remaining() const { return bytes_.size() - offset_; }
  bool at_end() const { return offset_ == bytes_.size(); }
  // Throws InputError if payload bytes are left unread (a writer/reader mismatch).
  void expect_end() const;

  template <class T>
  T read() {
    static_assert(binary_detail::kIsBlittable<T>, "read() returns plain values");
    T value;
    read_bytes(&value, sizeof(T));
    return value;
  }
  template <class T>
  void read(T& value) {
    value = read<T>();
  }
  template <class T>
  std::vector<T> read_vector() {
    static_assert(binary_detail::kIsBlittable<T>, "read_vector() returns plain values");
    std::size_t count = read_count(sizeof(T), "array");
    std::vector<T> values(count);
    read_bytes(values.data(), count * sizeof(T));
    return values;
  }
  std::string read_string();
  template <class M>
  M read_matrix() {
    static_assert(binary_detail::IsDynamicEigen<M>::value, "read_matrix() returns MatrixX*");
    auto rows = read<std::uint64_t>();
    auto cols = read<std::uint64_t>();
    check_matrix_shape(rows, cols, M::RowsAtCompileTime, M::ColsAtCompileTime,
                       sizeof(typename M::Scalar));
    M matrix(static_cast<Eigen::Index>(rows), static_cast<Eigen::Index>(cols));
    read_bytes(matrix.data(), sizeof(typename M::Scalar) * matrix.size());
    return matrix;
  }
  void read_bytes(void* out, std::size_t size);

 private:
  BinaryReader(std::filesystem::path path, std::string bytes, std::size_t offset,
               std::uint32_t version);
  // Reads a uint64 element count and checks count * element_size fits in the bytes left.
  std::size_t read_count(std::size_t element_size, const char* what);
  void check_matrix_shape(std::uint64_t rows, std::uint64_t cols, int fixed_rows, int fixed_cols,
                          std::size_t scalar_size);
  [[noreturn]] void throw_truncated(std::size_t needed, const char* what) const;

  std::filesystem::path path_;
  std::string bytes_;       // the whole file; reads start after the header
  std::size_t offset_ = 0;  // next byte to read
  std::uint32_t version_ = 0;
};

}  // namespace fourd
