#include "pipeline/core/colmap_model.h"

#include <fmt/format.h>

#include <Eigen/Geometry>
#include <charconv>
#include <cstdint>
#include <cstring>
#include <cmath>
#include <map>
#include <nlohmann/json.hpp>
#include <set>
#include <sstream>
#include <string>
#include <string_view>

#include "pipeline/core/error.h"
#include "pipeline/core/files.h"

namespace fourd {
namespace {

namespace fs = std::filesystem;

// ---------------------------------------------------------------------------------------------
// Reading

// One line of a text file with its 1-based number, for error messages.
struct Line {
  int number = 0;
  std::string text;
};

std::vector<Line> read_lines(const fs::path& path) {
  if (!fs::is_regular_file(path)) {
    throw InputError(fmt::format("{}: file does not exist (a COLMAP text model needs it)",
                                 path.string()));
  }
  std::istringstream in(read_file(path));
  std::vector<Line> lines;
  std::string text;
  for (int number = 1; std::getline(in, text); ++number) {
    if (!text.empty() && text.back() == '\r') text.pop_back();  // files edited on Windows
    lines.push_back({number, std::move(text)});
  }
  return lines;
}

bool is_blank_or_comment(const std::string& text) {
  const auto first = text.find_first_not_of(" \t");
  return first == std::string::npos || text[first] == '#';
}

std::vector<std::string> split_whitespace(const std::string& text) {
  std::istringstream in(text);
  std::vector<std::string> tokens;
  std::string token;
  while (in >> token) tokens.push_back(token);
  return tokens;
}

// Formats errors as "<file>:<line>: <what>".
class LineContext {
 public:
  LineContext(const fs::path& file, int line) : file_(file.string()), line_(line) {}

  [[noreturn]] void fail(const std::string& what) const {
    throw InputError(fmt::format("{}:{}: {}", file_, line_, what));
  }

  long long to_int(const std::string& token, const char* what) const {
    long long value = 0;
    const char* end = token.data() + token.size();
    auto [ptr, ec] = std::from_chars(token.data(), end, value);
    if (ec != std::errc() || ptr != end) fail(fmt::format("{} '{}' is not an integer", what, token));
    return value;
  }

  double to_double(const std::string& token, const char* what) const {
    double value = 0;
    const char* end = token.data() + token.size();
    auto [ptr, ec] = std::from_chars(token.data(), end, value);
    if (ec != std::errc() || ptr != end || !std::isfinite(value)) {
      fail(fmt::format("{} '{}' is not a finite number", what, token));
    }
    return value;
  }

 private:
  std::string file_;
  int line_;
};

// Maps one COLMAP camera model's parameter list onto our OPENCV-style intrinsics.
Intrinsics intrinsics_from_model(const LineContext& at, const std::string& model,
                                 const std::vector<double>& p) {
  struct ModelInfo {
    const char* name;
    size_t params;
    const char* layout;
  };
  static const ModelInfo kModels[] = {
      {"SIMPLE_PINHOLE", 3, "f, cx, cy"},
      {"PINHOLE", 4, "fx, fy, cx, cy"},
      {"SIMPLE_RADIAL", 4, "f, cx, cy, k"},
      {"RADIAL", 5, "f, cx, cy, k1, k2"},
      {"OPENCV", 8, "fx, fy, cx, cy, k1, k2, p1, p2"},
  };
  const ModelInfo* info = nullptr;
  for (const auto& m : kModels) {
    if (model == m.name) info = &m;
  }
  if (!info) {
    at.fail(fmt::format(
        "unknown camera model '{}' (supported: SIMPLE_PINHOLE, PINHOLE, SIMPLE_RADIAL, RADIAL, "
        "OPENCV)",
        model));
  }
  if (p.size() != info->params) {
    at.fail(fmt::format("camera model {} expects {} parameters ({}), found {}", model,
                        info->params, info->layout, p.size()));
  }
  Intrinsics in;
  if (model == "PINHOLE" || model == "OPENCV") {
    in.fx = p[0];
    in.fy = p[1];
    in.cx = p[2];
    in.cy = p[3];
    if (model == "OPENCV") {
      in.k1 = p[4];
      in.k2 = p[5];
      in.p1 = p[6];
      in.p2 = p[7];
    }
  } else {  // the SIMPLE_* and RADIAL models share one focal length
    in.fx = in.fy = p[0];
    in.cx = p[1];
    in.cy = p[2];
    if (p.size() > 3) in.k1 = p[3];
    if (p.size() > 4) in.k2 = p[4];
  }
  return in;
}

std::map<long long, Intrinsics> read_cameras_txt(const fs::path& path) {
  std::map<long long, Intrinsics> cameras;
  for (const Line& line : read_lines(path)) {
    if (is_blank_or_comment(line.text)) continue;
    const LineContext at(path, line.number);
    const auto tokens = split_whitespace(line.text);
    if (tokens.size() < 4) {
      at.fail(fmt::format("expected CAMERA_ID MODEL WIDTH HEIGHT PARAMS..., found {} fields",
                          tokens.size()));
    }
    const long long id = at.to_int(tokens[0], "CAMERA_ID");
    std::vector<double> params;
    for (size_t i = 4; i < tokens.size(); ++i) params.push_back(at.to_double(tokens[i], "parameter"));
    Intrinsics in = intrinsics_from_model(at, tokens[1], params);
    const long long width = at.to_int(tokens[2], "WIDTH");
    const long long height = at.to_int(tokens[3], "HEIGHT");
    if (width <= 0 || height <= 0 || width > 1'000'000 || height > 1'000'000) {
      at.fail(fmt::format("camera {} has an invalid image size {}x{}", id, width, height));
    }
    in.width = static_cast<int>(width);
    in.height = static_cast<int>(height);
    if (!(in.fx > 0) || !(in.fy > 0)) {
      at.fail(fmt::format("camera {} has a non-positive focal length ({}, {})", id, in.fx, in.fy));
    }
    if (!cameras.emplace(id, in).second) at.fail(fmt::format("CAMERA_ID {} appears twice", id));
  }
  return cameras;
}

using ImageEntry = ColmapImage;

std::map<long long, ImageEntry> read_images_txt(const fs::path& path,
                                                const fs::path& cameras_path,
                                                const std::map<long long, Intrinsics>& cameras) {
  const auto lines = read_lines(path);
  std::map<long long, ImageEntry> images;
  std::map<std::string, int> name_line;  // camera name -> line that declared it
  for (size_t i = 0; i < lines.size(); ++i) {
    const Line& line = lines[i];
    if (is_blank_or_comment(line.text)) continue;
    const LineContext at(path, line.number);
    const auto tokens = split_whitespace(line.text);
    if (tokens.size() != 10) {
      at.fail(fmt::format(
          "expected IMAGE_ID QW QX QY QZ TX TY TZ CAMERA_ID NAME (10 fields), found {}",
          tokens.size()));
    }
    // The line after an image line is its POINTS2D list, empty or not (COLMAP's format). We
    // need no points, but a list that is not (X, Y, POINT3D_ID) triplets means a line is
    // missing, e.g. two image lines with no POINTS2D line between them.
    if (i + 1 < lines.size()) {
      ++i;
      const auto points = split_whitespace(lines[i].text);
      if (points.size() % 3 != 0) {
        LineContext(path, lines[i].number)
            .fail(fmt::format("expected the POINTS2D line of image {} (X Y POINT3D_ID triplets, "
                              "may be empty), found {} fields",
                              tokens[0], points.size()));
      }
    }

    const long long image_id = at.to_int(tokens[0], "IMAGE_ID");
    Eigen::Quaterniond q(at.to_double(tokens[1], "QW"), at.to_double(tokens[2], "QX"),
                         at.to_double(tokens[3], "QY"), at.to_double(tokens[4], "QZ"));
    const Eigen::Vector3d t(at.to_double(tokens[5], "TX"), at.to_double(tokens[6], "TY"),
                            at.to_double(tokens[7], "TZ"));
    const long long camera_id = at.to_int(tokens[8], "CAMERA_ID");
    const std::string& image_name = tokens[9];
    if (!(q.norm() > 1e-9)) at.fail(fmt::format("image {} has a zero quaternion", image_id));
    q.normalize();  // as COLMAP does: text files round quaternions to finite precision
    auto cam = cameras.find(camera_id);
    if (cam == cameras.end()) {
      at.fail(fmt::format("image {} ('{}') references CAMERA_ID {}, which {} does not define",
                          image_id, image_name, camera_id, cameras_path.string()));
    }

    ImageEntry entry;
    entry.image_id = image_id;
    entry.camera_id = camera_id;
    entry.image_name = image_name;
    entry.camera.name = fs::path(image_name).replace_extension().string();
    if (entry.camera.name.empty()) at.fail(fmt::format("image {} has an empty name", image_id));
    entry.camera.intrinsics = cam->second;
    entry.camera.camera_from_world.linear() = q.toRotationMatrix();
    entry.camera.camera_from_world.translation() = t;

    auto [previous, fresh] = name_line.emplace(entry.camera.name, line.number);
    if (!fresh) {
      at.fail(fmt::format("camera name '{}' (image '{}') is already used on line {}",
                          entry.camera.name, image_name, previous->second));
    }
    if (!images.emplace(image_id, std::move(entry)).second) {
      at.fail(fmt::format("IMAGE_ID {} appears twice", image_id));
    }
  }
  return images;
}

// The binary model (cameras.bin, images.bin) of COLMAP's reconstructions: little-endian,
// read through a bounds-checked cursor so a truncated file is an error naming it.
class BinaryCursor {
 public:
  explicit BinaryCursor(const fs::path& path) : path_(path), bytes_(read_file(path)) {}
  template <class T>
  T get(const char* what) {
    T value;
    if (bytes_.size() - at_ < sizeof(T)) fail(fmt::format("truncated in {}", what));
    std::memcpy(&value, bytes_.data() + at_, sizeof(T));
    at_ += sizeof(T);
    return value;
  }
  std::string get_string(const char* what) {
    const auto end = bytes_.find('\0', at_);
    if (end == std::string::npos) fail(fmt::format("truncated in {}", what));
    std::string out = bytes_.substr(at_, end - at_);
    at_ = end + 1;
    return out;
  }
  void skip(std::uint64_t count, std::size_t size, const char* what) {
    if (count > (bytes_.size() - at_) / size) fail(fmt::format("truncated in {}", what));
    at_ += count * size;
  }
  [[noreturn]] void fail(const std::string& what) const {
    throw InputError(fmt::format("{}: byte {}: {}", path_.string(), at_, what));
  }

 private:
  fs::path path_;
  std::string bytes_;
  std::size_t at_ = 0;
};

std::map<long long, Intrinsics> read_cameras_bin(const fs::path& path) {
  // COLMAP's model ids of the models intrinsics_from_model knows (others are refused there).
  static const std::map<int, std::pair<const char*, int>> kModels = {
      {0, {"SIMPLE_PINHOLE", 3}}, {1, {"PINHOLE", 4}}, {2, {"SIMPLE_RADIAL", 4}},
      {3, {"RADIAL", 5}},         {4, {"OPENCV", 8}}};
  BinaryCursor in(path);
  std::map<long long, Intrinsics> cameras;
  const auto count = in.get<std::uint64_t>("the camera count");
  for (std::uint64_t i = 0; i < count; ++i) {
    const long long id = in.get<std::int32_t>("CAMERA_ID");
    const int model_id = in.get<std::int32_t>("MODEL");
    const auto width = in.get<std::uint64_t>("WIDTH"), height = in.get<std::uint64_t>("HEIGHT");
    const auto model = kModels.find(model_id);
    if (model == kModels.end()) {
      in.fail(fmt::format("camera {} has COLMAP model id {} (supported: 0-4, SIMPLE_PINHOLE to "
                          "OPENCV)",
                          id, model_id));
    }
    std::vector<double> params;
    for (int k = 0; k < model->second.second; ++k) params.push_back(in.get<double>("PARAMS"));
    Intrinsics intr = intrinsics_from_model(LineContext(path, 0), model->second.first, params);
    if (width == 0 || height == 0 || width > 1'000'000 || height > 1'000'000 || !(intr.fx > 0) ||
        !(intr.fy > 0)) {
      in.fail(fmt::format("camera {} has an invalid size {}x{} or focal length", id, width, height));
    }
    intr.width = static_cast<int>(width);
    intr.height = static_cast<int>(height);
    if (!cameras.emplace(id, intr).second) in.fail(fmt::format("CAMERA_ID {} appears twice", id));
  }
  return cameras;
}

std::map<long long, ImageEntry> read_images_bin(const fs::path& path, const fs::path& cameras_path,
                                                const std::map<long long, Intrinsics>& cameras) {
  BinaryCursor in(path);
  std::map<long long, ImageEntry> images;
  const auto count = in.get<std::uint64_t>("the image count");
  for (std::uint64_t i = 0; i < count; ++i) {
    ImageEntry entry;
    entry.image_id = in.get<std::uint32_t>("IMAGE_ID");
    double q[4], t[3];
    for (double& v : q) v = in.get<double>("QVEC");
    for (double& v : t) v = in.get<double>("TVEC");
    entry.camera_id = in.get<std::uint32_t>("CAMERA_ID");
    entry.image_name = in.get_string("NAME");
    in.skip(in.get<std::uint64_t>("the POINTS2D count"), 24, "POINTS2D");
    Eigen::Quaterniond quat(q[0], q[1], q[2], q[3]);
    if (!(quat.norm() > 1e-9)) in.fail(fmt::format("image {} has a zero quaternion", entry.image_id));
    const auto cam = cameras.find(entry.camera_id);
    if (cam == cameras.end()) {
      in.fail(fmt::format("image {} ('{}') references CAMERA_ID {}, which {} does not define",
                          entry.image_id, entry.image_name, entry.camera_id, cameras_path.string()));
    }
    entry.camera.name = fs::path(entry.image_name).replace_extension().string();
    entry.camera.intrinsics = cam->second;
    entry.camera.camera_from_world.linear() = quat.normalized().toRotationMatrix();
    entry.camera.camera_from_world.translation() = Eigen::Vector3d(t[0], t[1], t[2]);
    const long long id = entry.image_id;
    if (!images.emplace(id, std::move(entry)).second) in.fail(fmt::format("IMAGE_ID {} appears twice", id));
  }
  return images;
}

// rig.json is optional on read (COLMAP's own model_converter output has none); when present
// it must agree with cameras.txt and images.txt.
void check_rig_json(const fs::path& path, const std::map<long long, Intrinsics>& cameras,
                    const std::map<long long, ImageEntry>& images) {
  const std::string file = path.string();
  nlohmann::json rigs;
  try {
    rigs = nlohmann::json::parse(read_file(path));
  } catch (const nlohmann::json::parse_error& e) {
    throw InputError(fmt::format("{}: not valid JSON: {}", file, e.what()));
  }
  auto fail = [&](size_t rig, const std::string& what) {
    throw InputError(fmt::format("{}: rig {}: {}", file, rig, what));
  };
  if (!rigs.is_array()) throw InputError(fmt::format("{}: expected a JSON array of rigs", file));
  for (size_t r = 0; r < rigs.size(); ++r) {
    const auto& rig = rigs[r];
    if (!rig.is_object() || !rig.contains("ref_camera_id") ||
        !rig["ref_camera_id"].is_number_integer() || !rig.contains("cameras") ||
        !rig["cameras"].is_array()) {
      fail(r, "expected {\"ref_camera_id\": <int>, \"cameras\": [...]}");
    }
    bool has_ref = false;
    for (const auto& c : rig["cameras"]) {
      if (!c.is_object() || !c.contains("camera_id") || !c["camera_id"].is_number_integer() ||
          !c.contains("image_prefix") || !c["image_prefix"].is_string()) {
        fail(r, "each camera needs an integer \"camera_id\" and a string \"image_prefix\"");
      }
      const long long id = c["camera_id"].get<long long>();
      const std::string prefix = c["image_prefix"].get<std::string>();
      if (!cameras.count(id)) fail(r, fmt::format("camera_id {} is not in cameras.txt", id));
      bool matched = false;
      for (const auto& [image_id, image] : images) {
        if (image.camera_id == id && image.camera.name.rfind(prefix, 0) == 0) matched = true;
      }
      if (!matched) {
        fail(r, fmt::format("no image of camera_id {} in images.txt starts with '{}'", id, prefix));
      }
      has_ref = has_ref || id == rig["ref_camera_id"].get<long long>();
    }
    if (!has_ref) {
      fail(r, fmt::format("ref_camera_id {} is not among its cameras",
                          rig["ref_camera_id"].get<long long>()));
    }
  }
}

// ---------------------------------------------------------------------------------------------
// Writing

void check_writable(const std::vector<Camera>& cameras) {
  if (cameras.empty()) throw InputError("write_colmap_model: the rig has no cameras");
  std::set<std::string> names;
  for (const Camera& c : cameras) {
    if (c.name.empty()) throw InputError("write_colmap_model: a camera has an empty name");
    if (c.name.find_first_of(" \t\r\n/\\") != std::string::npos) {
      throw InputError(fmt::format(
          "write_colmap_model: camera name '{}' contains whitespace or a path separator", c.name));
    }
    if (!names.insert(c.name).second) {
      throw InputError(fmt::format("write_colmap_model: camera name '{}' appears twice", c.name));
    }
    const Intrinsics& in = c.intrinsics;
    const bool finite = std::isfinite(in.fx) && std::isfinite(in.fy) && std::isfinite(in.cx) &&
                        std::isfinite(in.cy) && std::isfinite(in.k1) && std::isfinite(in.k2) &&
                        std::isfinite(in.p1) && std::isfinite(in.p2);
    if (in.width <= 0 || in.height <= 0 || !(in.fx > 0) || !(in.fy > 0) || !finite) {
      throw InputError(fmt::format(
          "write_colmap_model: camera '{}' has invalid intrinsics ({}x{}, fx {}, fy {})", c.name,
          in.width, in.height, in.fx, in.fy));
    }
    const Eigen::Matrix3d r = c.camera_from_world.linear();
    if (!((r.transpose() * r - Eigen::Matrix3d::Identity()).norm() < 1e-9) ||
        !(r.determinant() > 0) || !c.camera_from_world.translation().allFinite()) {
      throw InputError(fmt::format(
          "write_colmap_model: camera '{}' has a pose that is not a rigid transform", c.name));
    }
  }
}

// fmt's "{}" prints the shortest text that parses back to the same double; +0.0 turns the
// "-0" of a negated zero into "0", which reads better and means the same.
double printable(double v) { return v + 0.0; }

std::string cameras_txt(const std::vector<Camera>& cameras) {
  std::string out =
      "# Camera list with one line of data per camera:\n"
      "#   CAMERA_ID, MODEL, WIDTH, HEIGHT, PARAMS[]\n";
  out += fmt::format("# Number of cameras: {}\n", cameras.size());
  for (size_t i = 0; i < cameras.size(); ++i) {
    const Intrinsics& in = cameras[i].intrinsics;
    if (in.has_distortion()) {
      out += fmt::format("{} OPENCV {} {} {} {} {} {} {} {} {} {}\n", i + 1, in.width, in.height,
                         in.fx, in.fy, in.cx, in.cy, in.k1, in.k2, in.p1, in.p2);
    } else {
      out += fmt::format("{} PINHOLE {} {} {} {} {} {}\n", i + 1, in.width, in.height, in.fx,
                         in.fy, in.cx, in.cy);
    }
  }
  return out;
}

std::string images_txt(const std::vector<Camera>& cameras) {
  std::string out =
      "# Image list with two lines of data per image:\n"
      "#   IMAGE_ID, QW, QX, QY, QZ, TX, TY, TZ, CAMERA_ID, NAME\n"
      "#   POINTS2D[] as (X, Y, POINT3D_ID)\n";
  out += fmt::format("# Number of images: {}, mean observations per image: 0\n", cameras.size());
  for (size_t i = 0; i < cameras.size(); ++i) {
    const Camera& c = cameras[i];
    Eigen::Quaterniond q(Eigen::Matrix3d(c.camera_from_world.linear()));
    q.normalize();
    if (q.w() < 0) q.coeffs() = -q.coeffs();  // one of the two equal quaternions, always
    const Eigen::Vector3d t = c.camera_from_world.translation();
    out += fmt::format("{} {} {} {} {} {} {} {} {} {}.png\n\n", i + 1, printable(q.w()),
                       printable(q.x()), printable(q.y()), printable(q.z()), printable(t.x()),
                       printable(t.y()), printable(t.z()), i + 1, c.name);
  }
  return out;
}

std::string points3d_txt() {
  return "# 3D point list with one line of data per point:\n"
         "#   POINT3D_ID, X, Y, Z, R, G, B, ERROR, TRACK[] as (IMAGE_ID, POINT2D_IDX)\n"
         "# Number of points: 0, mean track length: 0\n";
}

std::string rig_json(const std::vector<Camera>& cameras) {
  nlohmann::json list = nlohmann::json::array();
  for (size_t i = 0; i < cameras.size(); ++i) {
    list.push_back({{"camera_id", i + 1}, {"image_prefix", cameras[i].name}});
  }
  nlohmann::json rigs = nlohmann::json::array();
  rigs.push_back({{"ref_camera_id", 1}, {"cameras", list}});
  return rigs.dump(2) + "\n";
}

}  // namespace

namespace {

struct Model {
  std::map<long long, Intrinsics> intrinsics;
  std::map<long long, ImageEntry> images;
};

Model read_model(const fs::path& dir) {
  if (!fs::is_directory(dir)) {
    throw InputError(fmt::format("{}: calibration folder does not exist", dir.string()));
  }
  const fs::path cameras_path = dir / "cameras.txt";
  Model model;
  if (!fs::exists(cameras_path) && fs::exists(dir / "cameras.bin")) {
    model.intrinsics = read_cameras_bin(dir / "cameras.bin");
    model.images = read_images_bin(dir / "images.bin", dir / "cameras.bin", model.intrinsics);
    if (model.images.empty()) {
      throw InputError(fmt::format("{}: lists no images", (dir / "images.bin").string()));
    }
    return model;
  }
  model.intrinsics = read_cameras_txt(cameras_path);
  model.images = read_images_txt(dir / "images.txt", cameras_path, model.intrinsics);
  if (model.images.empty()) {
    throw InputError(fmt::format("{}: lists no images (one per camera)", (dir / "images.txt").string()));
  }
  return model;
}

}  // namespace

std::vector<ColmapImage> read_colmap_images(const fs::path& dir) {
  const Model model = read_model(dir);
  std::vector<ColmapImage> images;
  images.reserve(model.images.size());
  for (const auto& [id, image] : model.images) images.push_back(image);
  return images;
}

std::vector<Camera> read_colmap_model(const fs::path& dir) {
  const Model model = read_model(dir);
  if (fs::exists(dir / "rig.json")) check_rig_json(dir / "rig.json", model.intrinsics, model.images);
  std::vector<Camera> cameras;
  cameras.reserve(model.images.size());
  for (const auto& [id, image] : model.images) cameras.push_back(image.camera);
  return cameras;
}

void write_colmap_model(const fs::path& dir, const std::vector<Camera>& cameras) {
  check_writable(cameras);
  ensure_directory(dir);
  write_file_atomic(dir / "cameras.txt", cameras_txt(cameras));
  write_file_atomic(dir / "images.txt", images_txt(cameras));
  write_file_atomic(dir / "points3D.txt", points3d_txt());
  write_file_atomic(dir / "rig.json", rig_json(cameras));
}

}  // namespace fourd
