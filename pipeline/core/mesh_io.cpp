#include "pipeline/core/mesh_io.h"

#include <fmt/format.h>

#include <algorithm>
#include <bit>
#include <charconv>
#include <cmath>
#include <cstring>
#include <functional>
#include <optional>
#include <string_view>
#include <type_traits>

#include "pipeline/core/error.h"
#include "pipeline/core/files.h"

namespace fourd {
namespace {

// ---------------------------------------------------------------------------------------------
// Text helpers shared by the PLY header, ASCII PLY and OBJ/MTL parsers.

bool is_space(char c) { return c == ' ' || c == '\t' || c == '\r' || c == '\f' || c == '\v'; }

std::string_view trim(std::string_view s) {
  while (!s.empty() && is_space(s.front())) s.remove_prefix(1);
  while (!s.empty() && is_space(s.back())) s.remove_suffix(1);
  return s;
}

// Next whitespace-separated token of `s` (empty at the end); advances `s` past it.
std::string_view next_token(std::string_view& s) {
  std::size_t begin = 0;
  while (begin < s.size() && is_space(s[begin])) ++begin;
  std::size_t end = begin;
  while (end < s.size() && !is_space(s[end])) ++end;
  std::string_view token = s.substr(begin, end - begin);
  s.remove_prefix(end);
  return token;
}

// Splits text into lines without copying; `number` counts from 1. Accepts \n and \r\n.
class LineReader {
 public:
  explicit LineReader(std::string_view text, std::size_t first_number = 1)
      : text_(text), number_(first_number - 1) {}
  bool next(std::string_view* line) {
    if (pos_ >= text_.size()) return false;
    std::size_t end = text_.find('\n', pos_);
    if (end == std::string_view::npos) end = text_.size();
    *line = text_.substr(pos_, end - pos_);
    if (!line->empty() && line->back() == '\r') line->remove_suffix(1);
    pos_ = end + 1;
    ++number_;
    return true;
  }
  std::size_t number() const { return number_; }
  std::size_t offset() const { return std::min(pos_, text_.size()); }

 private:
  std::string_view text_;
  std::size_t pos_ = 0;
  std::size_t number_;
};

template <class T>
std::optional<T> parse_number(std::string_view token) {
  if (!token.empty() && token.front() == '+') token.remove_prefix(1);  // from_chars rejects '+'
  T value{};
  auto [end, ec] = std::from_chars(token.data(), token.data() + token.size(), value);
  if (ec != std::errc() || end != token.data() + token.size() || token.empty()) return {};
  return value;
}

std::string lower_extension(const fs::path& path) {
  std::string ext = path.extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return ext;
}

// ---------------------------------------------------------------------------------------------
// PLY header.

enum class PlyType : std::uint8_t {
  kInt8,
  kUint8,
  kInt16,
  kUint16,
  kInt32,
  kUint32,
  kFloat32,
  kFloat64
};

std::optional<PlyType> parse_ply_type(std::string_view name) {
  if (name == "char" || name == "int8") return PlyType::kInt8;
  if (name == "uchar" || name == "uint8") return PlyType::kUint8;
  if (name == "short" || name == "int16") return PlyType::kInt16;
  if (name == "ushort" || name == "uint16") return PlyType::kUint16;
  if (name == "int" || name == "int32") return PlyType::kInt32;
  if (name == "uint" || name == "uint32") return PlyType::kUint32;
  if (name == "float" || name == "float32") return PlyType::kFloat32;
  if (name == "double" || name == "float64") return PlyType::kFloat64;
  return {};
}

std::size_t ply_type_size(PlyType type) {
  switch (type) {
    case PlyType::kInt8:
    case PlyType::kUint8:
      return 1;
    case PlyType::kInt16:
    case PlyType::kUint16:
      return 2;
    case PlyType::kInt32:
    case PlyType::kUint32:
    case PlyType::kFloat32:
      return 4;
    case PlyType::kFloat64:
      return 8;
  }
  return 0;
}

bool is_float_type(PlyType type) { return type == PlyType::kFloat32 || type == PlyType::kFloat64; }

struct PlyProperty {
  std::string name;
  PlyType type = PlyType::kFloat32;  // the item type for lists
  bool is_list = false;
  PlyType count_type = PlyType::kUint8;
};

struct PlyElement {
  std::string name;
  std::size_t count = 0;
  std::vector<PlyProperty> properties;

  // Index of the scalar (or list) property called `name`, -1 when absent.
  int find(std::string_view property, bool list = false) const {
    for (std::size_t i = 0; i < properties.size(); ++i) {
      if (properties[i].name == property && properties[i].is_list == list) {
        return static_cast<int>(i);
      }
    }
    return -1;
  }
};

enum class PlyEncoding { kAscii, kBinaryLittleEndian, kBinaryBigEndian };

struct PlyHeader {
  PlyEncoding encoding = PlyEncoding::kAscii;
  std::vector<PlyElement> elements;
  std::string texture;              // from MeshLab's "comment TextureFile <name>"
  std::size_t data_offset = 0;      // first byte after the end_header line
  std::size_t data_first_line = 0;  // line number of the first data line (ASCII)
};

PlyHeader parse_ply_header(std::string_view bytes, const std::string& file) {
  PlyHeader header;
  LineReader lines(bytes);
  std::string_view line;
  auto fail = [&](std::string_view problem) -> InputError {
    return InputError(fmt::format("{}:{}: {}", file, lines.number(), problem));
  };
  if (!lines.next(&line) || trim(line) != "ply") {
    throw InputError(fmt::format("{}: not a PLY file (the first line is not \"ply\")", file));
  }
  bool have_format = false;
  while (true) {
    if (!lines.next(&line)) {
      throw InputError(fmt::format("{}: truncated: the PLY header has no end_header line", file));
    }
    std::string_view rest = line;
    std::string_view keyword = next_token(rest);
    if (keyword == "end_header") break;
    if (keyword.empty() || keyword == "obj_info") continue;
    if (keyword == "comment") {
      std::string_view text = trim(rest);
      if (text.starts_with("TextureFile")) header.texture = trim(text.substr(11));
      continue;
    }
    if (keyword == "format") {
      std::string_view encoding = next_token(rest);
      if (encoding == "ascii") {
        header.encoding = PlyEncoding::kAscii;
      } else if (encoding == "binary_little_endian") {
        header.encoding = PlyEncoding::kBinaryLittleEndian;
      } else if (encoding == "binary_big_endian") {
        header.encoding = PlyEncoding::kBinaryBigEndian;
      } else {
        throw fail(fmt::format("unknown PLY format \"{}\"", encoding));
      }
      have_format = true;
    } else if (keyword == "element") {
      PlyElement element;
      element.name = next_token(rest);
      auto count = parse_number<std::uint64_t>(next_token(rest));
      if (element.name.empty() || !count) throw fail("expected \"element <name> <count>\"");
      element.count = *count;
      header.elements.push_back(std::move(element));
    } else if (keyword == "property") {
      if (header.elements.empty()) throw fail("property before any element");
      PlyProperty property;
      std::string_view type = next_token(rest);
      if (type == "list") {
        property.is_list = true;
        std::string_view count_type = next_token(rest);
        auto parsed = parse_ply_type(count_type);
        if (!parsed || is_float_type(*parsed)) {
          throw fail(fmt::format("bad list count type \"{}\"", count_type));
        }
        property.count_type = *parsed;
        type = next_token(rest);
      }
      auto parsed = parse_ply_type(type);
      if (!parsed) throw fail(fmt::format("unknown property type \"{}\"", type));
      property.type = *parsed;
      property.name = next_token(rest);
      if (property.name.empty()) throw fail("property without a name");
      header.elements.back().properties.push_back(std::move(property));
    } else {
      throw fail(fmt::format("unexpected \"{}\" in the PLY header", keyword));
    }
  }
  if (!have_format) throw InputError(fmt::format("{}: the PLY header has no format line", file));
  header.data_offset = lines.offset();
  header.data_first_line = lines.number() + 1;
  return header;
}

// ---------------------------------------------------------------------------------------------
// PLY bodies. Both sources hand out one scalar at a time as a double (exact for every PLY
// integer type); the binary one decodes with memcpy straight from the file's bytes.

template <class T>
T load_scalar(const char* p, bool swap) {
  T value;
  if (swap) {
    char reversed[sizeof(T)];
    std::reverse_copy(p, p + sizeof(T), reversed);
    std::memcpy(&value, reversed, sizeof(T));
  } else {
    std::memcpy(&value, p, sizeof(T));
  }
  return value;
}

double decode_scalar(const char* p, PlyType type, bool swap) {
  switch (type) {
    case PlyType::kInt8:
      return load_scalar<std::int8_t>(p, swap);
    case PlyType::kUint8:
      return load_scalar<std::uint8_t>(p, swap);
    case PlyType::kInt16:
      return load_scalar<std::int16_t>(p, swap);
    case PlyType::kUint16:
      return load_scalar<std::uint16_t>(p, swap);
    case PlyType::kInt32:
      return load_scalar<std::int32_t>(p, swap);
    case PlyType::kUint32:
      return load_scalar<std::uint32_t>(p, swap);
    case PlyType::kFloat32:
      return load_scalar<float>(p, swap);
    case PlyType::kFloat64:
      return load_scalar<double>(p, swap);
  }
  return 0;
}

class PlyBinarySource {
 public:
  PlyBinarySource(std::string_view data, bool big_endian, const std::string& file)
      : data_(data), swap_(big_endian != (std::endian::native == std::endian::big)), file_(file) {}

  void begin(const PlyElement& element, std::size_t index) {
    element_ = &element;
    index_ = index;
  }
  void end() {}
  double scalar(PlyType type) {
    const std::size_t size = ply_type_size(type);
    if (size > data_.size() - pos_) throw truncated();
    double value = decode_scalar(data_.data() + pos_, type, swap_);
    pos_ += size;
    return value;
  }
  // Throws unless `count` values of `type` fit in what is left (before allocating for them).
  void check_list(PlyType type, std::size_t count) const {
    if (count > (data_.size() - pos_) / ply_type_size(type)) throw truncated();
  }
  void skip(PlyType type, std::size_t count) {
    check_list(type, count);
    pos_ += count * ply_type_size(type);
  }
  // All records of an element whose records have a fixed size (no lists), checked to fit at
  // once: the fast path for vertices.
  std::string_view take_records(const PlyElement& element, std::size_t record_size) {
    const std::size_t available = (data_.size() - pos_) / record_size;
    if (element.count > available) {
      begin(element, available);
      throw truncated();
    }
    std::string_view records = data_.substr(pos_, element.count * record_size);
    pos_ += records.size();
    return records;
  }
  bool swap() const { return swap_; }
  // Upper bound on the records left, to reserve memory without trusting the header's count.
  std::size_t max_records() const { return data_.size() - pos_; }
  InputError fail(std::string_view problem) const {
    return InputError(fmt::format("{}: {} {}: {}", file_, element_->name, index_, problem));
  }

 private:
  InputError truncated() const {
    return InputError(fmt::format("{}: truncated: the file ends inside {} {} of {}", file_,
                                  element_->name, index_, element_->count));
  }

  std::string_view data_;
  std::size_t pos_ = 0;
  bool swap_;
  const std::string& file_;
  const PlyElement* element_ = nullptr;
  std::size_t index_ = 0;
};

// ASCII PLY: one record per line, which is how every writer lays it out and lets errors
// name the line.
class PlyAsciiSource {
 public:
  PlyAsciiSource(std::string_view data, std::size_t first_line, const std::string& file)
      : lines_(data, first_line), data_size_(data.size()), file_(file) {}

  void begin(const PlyElement& element, std::size_t index) {
    do {
      if (!lines_.next(&line_)) {
        throw InputError(fmt::format("{}: truncated: the file ends before {} {} of {}", file_,
                                     element.name, index, element.count));
      }
    } while (trim(line_).empty());
  }
  void end() {
    if (!trim(line_).empty()) throw fail("more values than the header declares");
  }
  double scalar(PlyType) {
    std::string_view token = next_token(line_);
    if (token.empty()) throw fail("fewer values than the header declares");
    auto value = parse_number<double>(token);
    if (!value) throw fail(fmt::format("\"{}\" is not a number", token));
    return *value;
  }
  // Each value takes at least two characters (digit and separator) of the line.
  void check_list(PlyType, std::size_t count) const {
    if (count > (line_.size() + 1) / 2) throw fail("fewer values than the list length");
  }
  void skip(PlyType type, std::size_t count) {
    check_list(type, count);
    for (std::size_t i = 0; i < count; ++i) scalar(type);
  }
  std::size_t max_records() const { return data_size_ - lines_.offset(); }
  InputError fail(std::string_view problem) const {
    return InputError(fmt::format("{}:{}: {}", file_, lines_.number(), problem));
  }

 private:
  LineReader lines_;
  std::size_t data_size_;
  std::string_view line_;
  const std::string& file_;
};

template <class Source>
std::size_t read_list_length(Source& source, const PlyProperty& property) {
  double length = source.scalar(property.count_type);
  if (length < 0 || length != std::floor(length)) {
    throw source.fail(fmt::format("bad list length {} for {}", length, property.name));
  }
  source.check_list(property.type, static_cast<std::size_t>(length));
  return static_cast<std::size_t>(length);
}

template <class Source>
void skip_property(Source& source, const PlyProperty& property) {
  if (property.is_list) {
    source.skip(property.type, read_list_length(source, property));
  } else {
    source.scalar(property.type);
  }
}

// First scalar property of `element` named like one of `names`, -1 when none.
int find_any(const PlyElement& element, std::initializer_list<std::string_view> names) {
  for (std::string_view name : names) {
    int index = element.find(name);
    if (index >= 0) return index;
  }
  return -1;
}

// Where the vertex attributes are among the vertex element's properties (-1: absent).
struct PlyVertexLayout {
  int position[3];
  int normal[3];
  int color[3];
  int uv[2];
  int confidence = -1;
  bool float_color = false;  // colours stored as 0..1 floats rather than 0..255 integers

  bool has(const int* indices, int n) const {
    return std::all_of(indices, indices + n, [](int i) { return i >= 0; });
  }
};

PlyVertexLayout vertex_layout(const PlyElement& e, const std::string& file) {
  PlyVertexLayout layout{};
  layout.position[0] = e.find("x");
  layout.position[1] = e.find("y");
  layout.position[2] = e.find("z");
  if (!layout.has(layout.position, 3)) {
    throw InputError(fmt::format("{}: the vertex element has no x, y and z properties", file));
  }
  layout.normal[0] = e.find("nx");
  layout.normal[1] = e.find("ny");
  layout.normal[2] = e.find("nz");
  layout.color[0] = find_any(e, {"red", "diffuse_red", "r"});
  layout.color[1] = find_any(e, {"green", "diffuse_green", "g"});
  layout.color[2] = find_any(e, {"blue", "diffuse_blue", "b"});
  if (layout.has(layout.color, 3)) {
    layout.float_color = is_float_type(e.properties[layout.color[0]].type);
  }
  layout.uv[0] = find_any(e, {"s", "u", "texture_u", "texture_s"});
  layout.uv[1] = find_any(e, {"t", "v", "texture_v", "texture_t"});
  layout.confidence = e.find("confidence");
  return layout;
}

std::uint8_t to_color_byte(double value, bool is_float) {
  double scaled = is_float ? value * 255.0 : value;
  if (std::isnan(scaled)) return 0;  // clamp passes NaN through, and NaN -> uint8 is undefined
  return static_cast<std::uint8_t>(std::clamp(std::round(scaled), 0.0, 255.0));
}

template <class Source>
void read_ply_vertices(Source& source, const PlyElement& element, const std::string& file,
                       Mesh& mesh) {
  const PlyVertexLayout layout = vertex_layout(element, file);
  const bool has_normals = layout.has(layout.normal, 3);
  const bool has_colors = layout.has(layout.color, 3);
  const bool has_uvs = layout.has(layout.uv, 2);
  const bool has_confidence = layout.confidence >= 0;
  const std::size_t reserve = std::min(element.count, source.max_records());
  mesh.positions.reserve(reserve);
  if (has_normals) mesh.normals.reserve(reserve);
  if (has_colors) mesh.colors.reserve(reserve);
  if (has_uvs) mesh.uvs.reserve(reserve);
  if (has_confidence) mesh.confidence.reserve(reserve);

  // Appends one vertex given the value of each property (by index).
  auto append = [&](auto value) {
    auto vec3 = [&](const int* p) {
      return Vec3f(static_cast<float>(value(p[0])), static_cast<float>(value(p[1])),
                   static_cast<float>(value(p[2])));
    };
    mesh.positions.push_back(vec3(layout.position));
    if (has_normals) mesh.normals.push_back(vec3(layout.normal));
    if (has_colors) {
      const int* c = layout.color;
      mesh.colors.emplace_back(to_color_byte(value(c[0]), layout.float_color),
                               to_color_byte(value(c[1]), layout.float_color),
                               to_color_byte(value(c[2]), layout.float_color));
    }
    if (has_uvs) {
      mesh.uvs.emplace_back(static_cast<float>(value(layout.uv[0])),
                            static_cast<float>(value(layout.uv[1])));
    }
    if (has_confidence) mesh.confidence.push_back(static_cast<float>(value(layout.confidence)));
  };

  const auto& properties = element.properties;
  if constexpr (std::is_same_v<Source, PlyBinarySource>) {
    // Binary records without lists have a fixed size: decode straight from known offsets.
    if (std::none_of(properties.begin(), properties.end(), [](auto& p) { return p.is_list; })) {
      std::vector<std::size_t> offsets;
      std::size_t record_size = 0;
      for (const PlyProperty& property : properties) {
        offsets.push_back(record_size);
        record_size += ply_type_size(property.type);
      }
      const std::string_view records = source.take_records(element, record_size);
      const bool swap = source.swap();
      for (std::size_t i = 0; i < element.count; ++i) {
        const char* record = records.data() + i * record_size;
        append([&](int p) -> double {
          const char* at = record + offsets[p];
          if (!swap && properties[p].type == PlyType::kFloat32) {
            float value;  // the common case (fourd's own files), without the type switch
            std::memcpy(&value, at, sizeof(value));
            return value;
          }
          return decode_scalar(at, properties[p].type, swap);
        });
      }
      return;
    }
  }
  std::vector<double> values(properties.size());
  for (std::size_t i = 0; i < element.count; ++i) {
    source.begin(element, i);
    for (std::size_t p = 0; p < properties.size(); ++p) {
      if (properties[p].is_list) {
        skip_property(source, properties[p]);
      } else {
        values[p] = source.scalar(properties[p].type);
      }
    }
    source.end();
    append([&](int p) { return values[p]; });
  }
}

// Per-corner texture coordinates of the faces (MeshLab's "texcoord" face list).
struct PlyCornerUvs {
  std::vector<Vec2f> uvs;
  std::vector<Tri> triangles;
};

// Faces are fan-triangulated: (c0, c1, c2), (c0, c2, c3), ...
template <class Source>
void read_ply_faces(Source& source, const PlyElement& element, std::size_t num_vertices,
                    const std::string& file, Mesh& mesh, PlyCornerUvs& corner_uvs) {
  int index_property = element.find("vertex_indices", true);
  if (index_property < 0) index_property = element.find("vertex_index", true);
  if (index_property < 0) {
    throw InputError(fmt::format("{}: the face element has no vertex_indices list", file));
  }
  const int uv_property = element.find("texcoord", true);
  mesh.triangles.reserve(std::min(element.count, source.max_records()));

  std::vector<int> corners;
  std::vector<Vec2f> uvs;
  for (std::size_t f = 0; f < element.count; ++f) {
    source.begin(element, f);
    for (std::size_t p = 0; p < element.properties.size(); ++p) {
      const PlyProperty& property = element.properties[p];
      if (static_cast<int>(p) == index_property) {
        corners.resize(read_list_length(source, property));
        for (int& corner : corners) {
          double index = source.scalar(property.type);
          if (index < 0 || index >= static_cast<double>(num_vertices) ||
              index != std::floor(index)) {
            throw source.fail(
                fmt::format("vertex index {} out of range ({} vertices)", index, num_vertices));
          }
          corner = static_cast<int>(index);
        }
      } else if (static_cast<int>(p) == uv_property) {
        const std::size_t values = read_list_length(source, property);
        if (values % 2 != 0) throw source.fail(fmt::format("odd texcoord length {}", values));
        uvs.resize(values / 2);
        for (Vec2f& uv : uvs) {
          uv.x() = static_cast<float>(source.scalar(property.type));
          uv.y() = static_cast<float>(source.scalar(property.type));
        }
      } else {
        skip_property(source, property);
      }
    }
    source.end();
    if (corners.size() < 3) throw source.fail(fmt::format("face with {} vertices", corners.size()));
    if (uv_property >= 0 && uvs.size() != corners.size()) {
      throw source.fail(
          fmt::format("{} texture coordinates for {} corners", uvs.size(), corners.size()));
    }
    const int uv_base = static_cast<int>(corner_uvs.uvs.size());
    for (std::size_t k = 1; k + 1 < corners.size(); ++k) {
      mesh.triangles.emplace_back(corners[0], corners[k], corners[k + 1]);
      if (uv_property >= 0) {
        corner_uvs.triangles.emplace_back(uv_base, uv_base + static_cast<int>(k),
                                          uv_base + static_cast<int>(k) + 1);
      }
    }
    corner_uvs.uvs.insert(corner_uvs.uvs.end(), uvs.begin(), uvs.end());
  }
}

template <class Source>
void read_ply_body(Source& source, const PlyHeader& header, const std::string& file, Mesh& mesh) {
  std::size_t num_vertices = 0;
  bool have_vertices = false;
  for (const PlyElement& element : header.elements) {
    if (element.name == "vertex") {
      num_vertices = element.count;
      have_vertices = true;
    }
  }
  if (!have_vertices) throw InputError(fmt::format("{}: no vertex element", file));

  PlyCornerUvs corner_uvs;
  for (const PlyElement& element : header.elements) {
    if (element.name == "vertex") {
      read_ply_vertices(source, element, file, mesh);
    } else if (element.name == "face") {
      read_ply_faces(source, element, num_vertices, file, mesh, corner_uvs);
    } else {
      for (std::size_t i = 0; i < element.count; ++i) {
        source.begin(element, i);
        for (const PlyProperty& property : element.properties) skip_property(source, property);
        source.end();
      }
    }
  }
  // Per-corner coordinates are the more precise of the two when a file has both.
  if (!corner_uvs.triangles.empty()) {
    mesh.uvs = std::move(corner_uvs.uvs);
    mesh.uv_triangles = std::move(corner_uvs.triangles);
  }
}

// ---------------------------------------------------------------------------------------------
// PLY writer.

template <class T>
void store_little_endian(char*& out, T value) {
  std::memcpy(out, &value, sizeof(T));
  if constexpr (std::endian::native == std::endian::big) std::reverse(out, out + sizeof(T));
  out += sizeof(T);
}

std::string ply_header(const Mesh& mesh, PlyFormat format) {
  const bool corner_uvs = !mesh.uv_triangles.empty();
  std::string h = "ply\n";
  h += format == PlyFormat::kAscii ? "format ascii 1.0\n" : "format binary_little_endian 1.0\n";
  h += "comment written by fourd\n";
  if (!mesh.texture.empty()) h += fmt::format("comment TextureFile {}\n", mesh.texture);
  h += fmt::format("element vertex {}\n", mesh.num_vertices());
  h += "property float x\nproperty float y\nproperty float z\n";
  if (!mesh.normals.empty()) h += "property float nx\nproperty float ny\nproperty float nz\n";
  if (!mesh.colors.empty()) h += "property uchar red\nproperty uchar green\nproperty uchar blue\n";
  if (!mesh.uvs.empty() && !corner_uvs) h += "property float s\nproperty float t\n";
  if (!mesh.confidence.empty()) h += "property float confidence\n";
  h += fmt::format("element face {}\n", mesh.num_triangles());
  h += "property list uchar int vertex_indices\n";
  // MeshLab's convention for per-corner ("wedge") texture coordinates.
  if (corner_uvs) h += "property list uchar float texcoord\n";
  h += "end_header\n";
  return h;
}

std::string ply_binary_body(const Mesh& mesh) {
  const bool normals = !mesh.normals.empty();
  const bool colors = !mesh.colors.empty();
  const bool corner_uvs = !mesh.uv_triangles.empty();
  const bool vertex_uvs = !mesh.uvs.empty() && !corner_uvs;
  const bool confidence = !mesh.confidence.empty();
  const std::size_t vertex_size =
      12 + (normals ? 12 : 0) + (colors ? 3 : 0) + (vertex_uvs ? 8 : 0) + (confidence ? 4 : 0);
  const std::size_t face_size = 13 + (corner_uvs ? 25 : 0);
  std::string body(mesh.num_vertices() * vertex_size + mesh.num_triangles() * face_size, '\0');
  char* out = body.data();
  for (std::size_t i = 0; i < mesh.num_vertices(); ++i) {
    for (int k = 0; k < 3; ++k) store_little_endian(out, mesh.positions[i][k]);
    if (normals) {
      for (int k = 0; k < 3; ++k) store_little_endian(out, mesh.normals[i][k]);
    }
    if (colors) {
      for (int k = 0; k < 3; ++k) store_little_endian(out, mesh.colors[i][k]);
    }
    if (vertex_uvs) {
      for (int k = 0; k < 2; ++k) store_little_endian(out, mesh.uvs[i][k]);
    }
    if (confidence) store_little_endian(out, mesh.confidence[i]);
  }
  for (std::size_t f = 0; f < mesh.num_triangles(); ++f) {
    store_little_endian(out, std::uint8_t{3});
    for (int k = 0; k < 3; ++k) store_little_endian(out, std::int32_t{mesh.triangles[f][k]});
    if (corner_uvs) {
      store_little_endian(out, std::uint8_t{6});
      for (int k = 0; k < 3; ++k) {
        const Vec2f& uv = mesh.uvs[mesh.uv_triangles[f][k]];
        store_little_endian(out, uv.x());
        store_little_endian(out, uv.y());
      }
    }
  }
  return body;
}

std::string ply_ascii_body(const Mesh& mesh) {
  const bool corner_uvs = !mesh.uv_triangles.empty();
  const bool vertex_uvs = !mesh.uvs.empty() && !corner_uvs;
  fmt::memory_buffer out;
  auto put = std::back_inserter(out);
  for (std::size_t i = 0; i < mesh.num_vertices(); ++i) {
    const Vec3f& p = mesh.positions[i];
    fmt::format_to(put, "{} {} {}", p.x(), p.y(), p.z());
    if (!mesh.normals.empty()) {
      const Vec3f& n = mesh.normals[i];
      fmt::format_to(put, " {} {} {}", n.x(), n.y(), n.z());
    }
    if (!mesh.colors.empty()) {
      const Rgb8& c = mesh.colors[i];
      fmt::format_to(put, " {} {} {}", int{c[0]}, int{c[1]}, int{c[2]});
    }
    if (vertex_uvs) fmt::format_to(put, " {} {}", mesh.uvs[i].x(), mesh.uvs[i].y());
    if (!mesh.confidence.empty()) fmt::format_to(put, " {}", mesh.confidence[i]);
    out.push_back('\n');
  }
  for (std::size_t f = 0; f < mesh.num_triangles(); ++f) {
    const Tri& t = mesh.triangles[f];
    fmt::format_to(put, "3 {} {} {}", t[0], t[1], t[2]);
    if (corner_uvs) {
      out.append(std::string_view(" 6"));
      for (int k = 0; k < 3; ++k) {
        const Vec2f& uv = mesh.uvs[mesh.uv_triangles[f][k]];
        fmt::format_to(put, " {} {}", uv.x(), uv.y());
      }
    }
    out.push_back('\n');
  }
  return fmt::to_string(out);
}

// ---------------------------------------------------------------------------------------------
// OBJ + MTL.

constexpr std::string_view kObjMaterial = "material_0";

// One corner of an OBJ face, as 0-based indices (-1: absent).
struct ObjCorner {
  int v = -1, vt = -1, vn = -1;
};

// Resolves a 1-based or negative (relative to the `count` elements defined so far) index.
int resolve_obj_index(std::string_view token, std::size_t count, const char* kind,
                      const std::function<InputError(std::string_view)>& fail) {
  auto index = parse_number<long long>(token);
  if (!index || *index == 0) throw fail(fmt::format("bad {} index \"{}\"", kind, token));
  long long resolved = *index > 0 ? *index - 1 : static_cast<long long>(count) + *index;
  if (resolved < 0 || resolved >= static_cast<long long>(count)) {
    throw fail(fmt::format("{} index {} out of range ({} defined so far)", kind, *index, count));
  }
  return static_cast<int>(resolved);
}

// Skips map_Kd options ("-s 1 1 1", "-clamp on", ...) and returns the file name after them.
std::string_view map_file_name(std::string_view rest) {
  rest = trim(rest);
  while (rest.starts_with("-")) {
    std::string_view option = next_token(rest);
    const bool takes_word = option == "-blendu" || option == "-blendv" || option == "-cc" ||
                            option == "-clamp" || option == "-imfchan" || option == "-type";
    if (takes_word) {
      next_token(rest);
    } else {
      // Numeric options take one to three numbers.
      std::string_view probe = rest;
      while (parse_number<double>(next_token(probe))) rest = probe;
    }
    rest = trim(rest);
  }
  return rest;
}

// map_Kd of `material` (any material when empty) in the .mtl file, as a path relative to the
// OBJ file's folder; "" if the file or the material does not exist (a missing material
// library is common and not fatal).
std::string read_mtl_texture(const fs::path& obj_dir, std::string_view mtllib,
                             std::string_view material) {
  const fs::path mtl_path = obj_dir / fs::path(std::string(mtllib));
  std::error_code ec;  // a name the file system refuses (too long, ...) is a missing library
  if (!fs::is_regular_file(mtl_path, ec)) return "";
  const std::string text = read_file(mtl_path);
  LineReader lines(text);
  std::string_view line;
  bool in_material = false;
  while (lines.next(&line)) {
    std::string_view rest = line;
    std::string_view keyword = next_token(rest);
    if (keyword == "newmtl") {
      // Faces without usemtl: the first material that has a texture.
      in_material = material.empty() || trim(rest) == material;
    } else if (in_material && keyword == "map_Kd") {
      std::string name(map_file_name(rest));
      std::replace(name.begin(), name.end(), '\\', '/');
      if (name.empty()) return "";
      fs::path texture(name);
      if (texture.is_absolute()) return texture.generic_string();
      return (fs::path(std::string(mtllib)).parent_path() / texture)
          .lexically_normal()
          .generic_string();
    }
  }
  return "";
}

struct ObjData {
  std::vector<Vec3f> positions;
  std::vector<Rgb8> colors;
  std::size_t positions_with_color = 0;
  std::vector<Vec2f> uvs;
  std::vector<Vec3f> normals;
  std::vector<ObjCorner> corners;  // 3 per triangle
  std::vector<std::string> mtllibs;
  std::string first_material;  // the first material a face uses
};

// Reads up to `max` numbers from the rest of a line into `out`; returns how many.
int parse_numbers(std::string_view rest, float* out, int max,
                  const std::function<InputError(std::string_view)>& fail) {
  int n = 0;
  for (std::string_view token = next_token(rest); !token.empty(); token = next_token(rest)) {
    if (n == max) throw fail("too many numbers");
    auto value = parse_number<float>(token);
    if (!value) throw fail(fmt::format("\"{}\" is not a number", token));
    out[n++] = *value;
  }
  return n;
}

ObjData parse_obj(std::string_view text, const std::string& file) {
  ObjData obj;
  LineReader lines(text);
  std::string_view line;
  const std::function<InputError(std::string_view)> fail = [&](std::string_view problem) {
    return InputError(fmt::format("{}:{}: {}", file, lines.number(), problem));
  };
  std::string current_material;
  std::vector<ObjCorner> face;
  float numbers[7];
  while (lines.next(&line)) {
    line = line.substr(0, line.find('#'));
    std::string_view rest = line;
    std::string_view keyword = next_token(rest);
    if (keyword == "v") {
      int n = parse_numbers(rest, numbers, 7, fail);
      if (n != 3 && n != 4 && n != 6 && n != 7)
        throw fail("a vertex needs x y z [w] or x y z r g b");
      obj.positions.emplace_back(numbers[0], numbers[1], numbers[2]);
      if (n >= 6) {
        // Vertex colours ("v x y z r g b", 0..1), the MeshLab/Blender extension.
        const float* rgb = numbers + (n - 3);
        obj.colors.resize(obj.positions.size(), Rgb8::Zero());
        obj.colors.back() = Rgb8(to_color_byte(rgb[0], true), to_color_byte(rgb[1], true),
                                 to_color_byte(rgb[2], true));
        ++obj.positions_with_color;
      }
    } else if (keyword == "vt") {
      int n = parse_numbers(rest, numbers, 3, fail);
      if (n < 1) throw fail("a texture coordinate needs u [v [w]]");
      obj.uvs.emplace_back(numbers[0], n > 1 ? numbers[1] : 0.f);
    } else if (keyword == "vn") {
      if (parse_numbers(rest, numbers, 3, fail) != 3) throw fail("a normal needs x y z");
      obj.normals.emplace_back(numbers[0], numbers[1], numbers[2]);
    } else if (keyword == "f") {
      face.clear();
      for (std::string_view token = next_token(rest); !token.empty(); token = next_token(rest)) {
        ObjCorner corner;
        std::size_t slash1 = token.find('/');
        corner.v = resolve_obj_index(token.substr(0, slash1), obj.positions.size(), "vertex", fail);
        if (slash1 != std::string_view::npos) {
          std::string_view tail = token.substr(slash1 + 1);
          std::size_t slash2 = tail.find('/');
          std::string_view vt = tail.substr(0, slash2);
          if (!vt.empty())
            corner.vt = resolve_obj_index(vt, obj.uvs.size(), "texture coordinate", fail);
          if (slash2 != std::string_view::npos) {
            corner.vn =
                resolve_obj_index(tail.substr(slash2 + 1), obj.normals.size(), "normal", fail);
          }
        }
        face.push_back(corner);
      }
      if (face.size() < 3) throw fail(fmt::format("face with {} vertices", face.size()));
      for (std::size_t k = 0; k < face.size(); ++k) {
        if ((face[k].vt < 0) != (face[0].vt < 0) || (face[k].vn < 0) != (face[0].vn < 0)) {
          throw fail("corners of one face mix forms (v, v/vt, v//vn, v/vt/vn)");
        }
      }
      if (!obj.corners.empty() && (face[0].vt < 0) != (obj.corners[0].vt < 0)) {
        throw fail("some faces have texture coordinates and others do not");
      }
      for (std::size_t k = 1; k + 1 < face.size(); ++k) {
        obj.corners.insert(obj.corners.end(), {face[0], face[k], face[k + 1]});
      }
      if (obj.first_material.empty()) obj.first_material = current_material;
    } else if (keyword == "mtllib") {
      std::string_view name = trim(rest);
      if (!name.empty()) obj.mtllibs.emplace_back(name);
    } else if (keyword == "usemtl") {
      current_material = trim(rest);
    }
    // Other statements (o, g, s, l, p, ...) carry nothing a Mesh stores.
  }
  return obj;
}

bool corners_match_vertices(const std::vector<ObjCorner>& corners, int ObjCorner::*member,
                            std::size_t count, std::size_t num_vertices) {
  if (count != num_vertices) return false;
  return std::all_of(corners.begin(), corners.end(),
                     [&](const ObjCorner& c) { return c.*member == c.v; });
}

Mesh mesh_from_obj(ObjData obj, const fs::path& path) {
  Mesh mesh;
  const std::size_t nv = obj.positions.size();
  mesh.positions = std::move(obj.positions);
  if (obj.positions_with_color == nv && nv > 0) mesh.colors = std::move(obj.colors);
  mesh.triangles.resize(obj.corners.size() / 3);
  for (std::size_t f = 0; f < mesh.triangles.size(); ++f) {
    for (int k = 0; k < 3; ++k) mesh.triangles[f][k] = obj.corners[3 * f + k].v;
  }
  const bool has_vt = !obj.corners.empty() && obj.corners[0].vt >= 0;
  if (has_vt) {
    // Per vertex when every corner uses its vertex's own index, as write_obj does for
    // per-vertex coordinates; per corner otherwise (UV seams).
    mesh.uvs = std::move(obj.uvs);
    if (!corners_match_vertices(obj.corners, &ObjCorner::vt, mesh.uvs.size(), nv)) {
      mesh.uv_triangles.resize(mesh.triangles.size());
      for (std::size_t f = 0; f < mesh.triangles.size(); ++f) {
        for (int k = 0; k < 3; ++k) mesh.uv_triangles[f][k] = obj.corners[3 * f + k].vt;
      }
    }
  }
  const bool has_vn =
      !obj.corners.empty() && std::all_of(obj.corners.begin(), obj.corners.end(),
                                          [](const ObjCorner& c) { return c.vn >= 0; });
  if (has_vn) {
    if (corners_match_vertices(obj.corners, &ObjCorner::vn, obj.normals.size(), nv)) {
      mesh.normals = std::move(obj.normals);
    } else {
      // Mesh normals are per vertex: average the corners' normals (hard edges get smoothed).
      mesh.normals.assign(nv, Vec3f::Zero());
      for (const ObjCorner& c : obj.corners) mesh.normals[c.v] += obj.normals[c.vn];
      for (Vec3f& n : mesh.normals) {
        if (n.norm() > 0) n.normalize();
      }
    }
  }
  const std::string material = obj.first_material;
  for (const std::string& mtllib : obj.mtllibs) {
    mesh.texture = read_mtl_texture(path.parent_path(), mtllib, material);
    if (!mesh.texture.empty()) break;
  }
  return mesh;
}

std::string obj_text(const Mesh& mesh, const std::string& mtl_name) {
  fmt::memory_buffer out;
  auto put = std::back_inserter(out);
  fmt::format_to(put, "# written by fourd: {} vertices, {} triangles\n", mesh.num_vertices(),
                 mesh.num_triangles());
  if (!mtl_name.empty()) fmt::format_to(put, "mtllib {}\n", mtl_name);
  for (std::size_t i = 0; i < mesh.num_vertices(); ++i) {
    const Vec3f& p = mesh.positions[i];
    fmt::format_to(put, "v {} {} {}", p.x(), p.y(), p.z());
    if (!mesh.colors.empty()) {
      const Rgb8& c = mesh.colors[i];
      fmt::format_to(put, " {} {} {}", c[0] / 255.f, c[1] / 255.f, c[2] / 255.f);
    }
    out.push_back('\n');
  }
  for (const Vec2f& uv : mesh.uvs) fmt::format_to(put, "vt {} {}\n", uv.x(), uv.y());
  for (const Vec3f& n : mesh.normals) fmt::format_to(put, "vn {} {} {}\n", n.x(), n.y(), n.z());
  if (!mtl_name.empty()) fmt::format_to(put, "usemtl {}\n", kObjMaterial);
  const bool uvs = !mesh.uvs.empty();
  const bool corner_uvs = !mesh.uv_triangles.empty();
  const bool normals = !mesh.normals.empty();
  for (std::size_t f = 0; f < mesh.num_triangles(); ++f) {
    out.push_back('f');
    for (int k = 0; k < 3; ++k) {
      const int v = mesh.triangles[f][k] + 1;
      const int vt = (corner_uvs ? mesh.uv_triangles[f][k] : mesh.triangles[f][k]) + 1;
      if (uvs && normals) {
        fmt::format_to(put, " {}/{}/{}", v, vt, v);
      } else if (uvs) {
        fmt::format_to(put, " {}/{}", v, vt);
      } else if (normals) {
        fmt::format_to(put, " {}//{}", v, v);
      } else {
        fmt::format_to(put, " {}", v);
      }
    }
    out.push_back('\n');
  }
  return fmt::to_string(out);
}

std::string mtl_text(const Mesh& mesh) {
  return fmt::format(
      "# written by fourd\n"
      "newmtl {}\n"
      "Ka 1 1 1\n"
      "Kd 1 1 1\n"
      "Ks 0 0 0\n"
      "d 1\n"
      "illum 1\n"
      "map_Kd {}\n",
      kObjMaterial, mesh.texture);
}

}  // namespace

Mesh read_ply(const fs::path& path) {
  const std::string file = path.string();
  const std::string bytes = read_file(path);
  const PlyHeader header = parse_ply_header(bytes, file);
  std::string_view data = std::string_view(bytes).substr(header.data_offset);
  Mesh mesh;
  if (header.encoding == PlyEncoding::kAscii) {
    PlyAsciiSource source(data, header.data_first_line, file);
    read_ply_body(source, header, file, mesh);
  } else {
    PlyBinarySource source(data, header.encoding == PlyEncoding::kBinaryBigEndian, file);
    read_ply_body(source, header, file, mesh);
  }
  mesh.texture = header.texture;
  mesh.check(file);
  return mesh;
}

void write_ply(const fs::path& path, const Mesh& mesh, PlyFormat format) {
  mesh.check(fmt::format("writing {}", path.string()));
  AtomicFile file(path);
  const std::string header = ply_header(mesh, format);
  const std::string body =
      format == PlyFormat::kAscii ? ply_ascii_body(mesh) : ply_binary_body(mesh);
  file.stream().write(header.data(), static_cast<std::streamsize>(header.size()));
  file.stream().write(body.data(), static_cast<std::streamsize>(body.size()));
  file.commit();
}

Mesh read_obj(const fs::path& path) {
  const std::string file = path.string();
  Mesh mesh = mesh_from_obj(parse_obj(read_file(path), file), path);
  mesh.check(file);
  return mesh;
}

void write_obj(const fs::path& path, const Mesh& mesh) {
  mesh.check(fmt::format("writing {}", path.string()));
  std::string mtl_name;
  if (!mesh.texture.empty()) {
    // The material library first, so the OBJ never names a file that is not there yet.
    fs::path mtl_path = path;
    mtl_path.replace_extension(".mtl");
    mtl_name = mtl_path.filename().string();
    write_file_atomic(mtl_path, mtl_text(mesh));
  }
  write_file_atomic(path, obj_text(mesh, mtl_name));
}

Mesh read_mesh(const fs::path& path) {
  const std::string ext = lower_extension(path);
  if (ext == ".ply") return read_ply(path);
  if (ext == ".obj") return read_obj(path);
  throw InputError(
      fmt::format("{}: unknown mesh file type (expected .ply or .obj)", path.string()));
}

void write_mesh(const fs::path& path, const Mesh& mesh) {
  const std::string ext = lower_extension(path);
  if (ext == ".ply") return write_ply(path, mesh);
  if (ext == ".obj") return write_obj(path, mesh);
  throw InputError(
      fmt::format("{}: unknown mesh file type (expected .ply or .obj)", path.string()));
}

}  // namespace fourd
