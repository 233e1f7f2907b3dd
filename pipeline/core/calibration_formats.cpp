#include "pipeline/core/calibration_formats.h"

#include <fmt/format.h>
#include <fnmatch.h>
#include <yaml-cpp/yaml.h>

#include <Eigen/Geometry>
#include <Eigen/SVD>
#include <algorithm>
#include <charconv>
#include <functional>
#include <cmath>
#include <map>
#include <nlohmann/json.hpp>
#include <opencv2/calib3d.hpp>
#include <opencv2/core/persistence.hpp>
#include <set>
#include <sstream>

#include "pipeline/core/colmap_model.h"
#include "pipeline/core/error.h"
#include "pipeline/core/files.h"

namespace fourd {
namespace {

namespace fs = std::filesystem;

std::string lower(std::string s) {
  std::transform(s.begin(), s.end(), s.begin(), [](unsigned char c) { return std::tolower(c); });
  return s;
}

std::string trim(const std::string& s) {
  const auto first = s.find_first_not_of(" \t\r\"");
  if (first == std::string::npos) return {};
  const auto last = s.find_last_not_of(" \t\r\"");
  return s.substr(first, last - first + 1);
}

Eigen::Matrix3d rodrigues(const Eigen::Vector3d& r) {
  const double angle = r.norm();
  if (angle == 0) return Eigen::Matrix3d::Identity();
  return Eigen::AngleAxisd(angle, r / angle).toRotationMatrix();
}

Eigen::Vector3d rodrigues_vector(const Eigen::Matrix3d& rotation) {
  const Eigen::AngleAxisd aa(rotation);
  return aa.angle() * aa.axis();
}

// A rotation given as 9 numbers (row-major 3x3) or 3 (Rodrigues axis-angle).
Eigen::Matrix3d rotation_from(const std::vector<double>& v, const std::string& where) {
  if (v.size() == 9) {
    Eigen::Matrix3d r;
    for (int i = 0; i < 9; ++i) r(i / 3, i % 3) = v[i];
    return r;
  }
  if (v.size() == 3) return rodrigues({v[0], v[1], v[2]});
  throw InputError(fmt::format("{}: a rotation has 9 numbers (3x3 matrix) or 3 (Rodrigues "
                               "vector), found {}",
                               where, v.size()));
}

Eigen::Vector3d vector3_from(const std::vector<double>& v, const std::string& where) {
  if (v.size() != 3) {
    throw InputError(fmt::format("{}: a translation has 3 numbers, found {}", where, v.size()));
  }
  return {v[0], v[1], v[2]};
}

// The camera's pixels-and-lengths in file terms, for the writers.
struct FileCamera {
  double fx, fy, cx, cy;  // OpenCV pixel convention
  std::vector<double> distortion;
  Eigen::Matrix3d rotation;  // camera_from_world
  Eigen::Vector3d translation;
};

FileCamera to_file_camera(const Camera& c, LengthUnit unit) {
  const Intrinsics& in = c.intrinsics;
  return {in.fx,
          in.fy,
          in.cx - 0.5,
          in.cy - 0.5,
          {in.k1, in.k2, in.p1, in.p2},
          c.camera_from_world.linear(),
          c.camera_from_world.translation() / metres_per_unit(unit)};
}

}  // namespace

// --- Units ------------------------------------------------------------------------------------

LengthUnit parse_length_unit(const std::string& text, const std::string& where) {
  const std::string t = lower(trim(text));
  if (t == "m" || t == "metre" || t == "meter" || t == "metres" || t == "meters") return LengthUnit::kMetre;
  if (t == "cm" || t == "centimetre" || t == "centimeter" || t == "centimetres" || t == "centimeters") {
    return LengthUnit::kCentimetre;
  }
  if (t == "mm" || t == "millimetre" || t == "millimeter" || t == "millimetres" || t == "millimeters") {
    return LengthUnit::kMillimetre;
  }
  throw ConfigError(fmt::format("{}: unknown length unit '{}' (known: m, cm, mm)", where, text));
}

double metres_per_unit(LengthUnit unit) {
  switch (unit) {
    case LengthUnit::kMetre: return 1.0;
    case LengthUnit::kCentimetre: return 0.01;
    case LengthUnit::kMillimetre: return 0.001;
  }
  return 1.0;
}

const char* unit_name(LengthUnit unit) {
  switch (unit) {
    case LengthUnit::kMetre: return "m";
    case LengthUnit::kCentimetre: return "cm";
    case LengthUnit::kMillimetre: return "mm";
  }
  return "m";
}

LengthUnit infer_length_unit(double median_camera_distance) {
  if (median_camera_distance < 50) return LengthUnit::kMetre;
  if (median_camera_distance < 1000) return LengthUnit::kCentimetre;
  return LengthUnit::kMillimetre;
}

// --- The shared conversion ---------------------------------------------------------------------

Camera record_to_camera(const CameraRecord& r, double metres_per_file_unit,
                        bool drop_higher_distortion, std::vector<std::string>* notes) {
  const std::string what = fmt::format("{}: camera '{}'", r.source, r.name);
  if (r.name.empty()) throw InputError(fmt::format("{}: a camera has no name", r.source));
  if (r.name.find_first_of(" \t\r\n/\\") != std::string::npos) {
    throw InputError(fmt::format("{}: the name contains whitespace or a path separator", what));
  }
  if (r.width <= 0 || r.height <= 0) {
    throw InputError(fmt::format("{}: invalid image size {}x{}", what, r.width, r.height));
  }
  if (!(r.fx > 0) || !(r.fy > 0) || !std::isfinite(r.fx) || !std::isfinite(r.fy)) {
    throw InputError(fmt::format("{}: focal lengths must be positive (fx {}, fy {})", what, r.fx, r.fy));
  }
  Camera c;
  c.name = r.name;
  Intrinsics& in = c.intrinsics;
  in.width = r.width;
  in.height = r.height;
  in.fx = r.fx;
  in.fy = r.fy;
  const double offset = r.colmap_pixels ? 0.0 : 0.5;
  in.cx = r.cx + offset;
  in.cy = r.cy + offset;
  if (!(in.cx >= 0 && in.cx <= in.width && in.cy >= 0 && in.cy <= in.height)) {
    throw InputError(fmt::format("{}: principal point ({}, {}) lies outside the {}x{} image", what,
                                 r.cx, r.cy, r.width, r.height));
  }
  const std::vector<double>& d = r.distortion;
  for (double v : d) {
    if (!std::isfinite(v)) throw InputError(fmt::format("{}: a distortion coefficient is not finite", what));
  }
  if (d.size() == 3) {
    throw InputError(fmt::format("{}: 3 distortion coefficients are ambiguous (expected k1 k2, or "
                                 "OpenCV's k1 k2 p1 p2 [k3 ...])",
                                 what));
  }
  if (d.size() >= 1) in.k1 = d[0];
  if (d.size() >= 2) in.k2 = d[1];
  if (d.size() >= 4) in.p1 = d[2], in.p2 = d[3];
  for (std::size_t i = 4; i < d.size(); ++i) {
    if (d[i] == 0) continue;
    if (!drop_higher_distortion) {
      throw InputError(fmt::format(
          "{}: distortion coefficient {} ({}) is not zero; the session's camera model has k1 k2 "
          "p1 p2 only (drop the higher terms explicitly to import it anyway)",
          what, i + 1, d[i]));
    }
    if (notes) notes->push_back(fmt::format("{}: dropped distortion coefficient {} ({})", r.name, i + 1, d[i]));
  }
  const Eigen::Matrix3d& rot = r.rotation;
  if (!rot.allFinite() || !r.translation.allFinite()) {
    throw InputError(fmt::format("{}: the pose is not finite", what));
  }
  const double orthonormality = (rot.transpose() * rot - Eigen::Matrix3d::Identity()).norm();
  if (!(orthonormality < 1e-6) || !(rot.determinant() > 0)) {
    throw InputError(fmt::format("{}: R is not a rotation (|R^T R - I| = {:.3g}, det {:.6g})", what,
                                 orthonormality, rot.determinant()));
  }
  // The nearest rotation (files round to finite precision; the COLMAP writer wants 1e-9).
  const Eigen::JacobiSVD<Eigen::Matrix3d> svd(rot, Eigen::ComputeFullU | Eigen::ComputeFullV);
  c.camera_from_world.linear() = svd.matrixU() * svd.matrixV().transpose();
  c.camera_from_world.translation() = r.translation * metres_per_file_unit;
  return c;
}

// --- COLMAP ------------------------------------------------------------------------------------

CalibrationRecords read_colmap_calibration(const fs::path& dir,
                                           const std::vector<std::string>& image_patterns) {
  const std::vector<ColmapImage> images = read_colmap_images(dir);
  std::vector<const ColmapImage*> selected;
  if (image_patterns.empty()) {
    std::set<long long> seen;
    for (const ColmapImage& image : images) {
      if (seen.insert(image.camera_id).second) selected.push_back(&image);
    }
  } else {
    for (const ColmapImage& image : images) {
      for (const std::string& pattern : image_patterns) {
        if (fnmatch(pattern.c_str(), image.image_name.c_str(), 0) == 0) {
          selected.push_back(&image);
          break;
        }
      }
    }
    if (selected.empty()) {
      std::string patterns;
      for (const auto& p : image_patterns) patterns += (patterns.empty() ? "" : ", ") + p;
      throw InputError(fmt::format("{}: no image NAME of images.txt matches {}", dir.string(), patterns));
    }
  }
  CalibrationRecords out;
  out.convention = "COLMAP text model: qvec/tvec world-to-camera, pixel centres at +0.5";
  std::map<std::string, std::string> by_name;  // camera name -> image NAME
  for (const ColmapImage* image : selected) {
    const fs::path name_path(image->image_name);
    CameraRecord r;
    r.name = name_path.has_parent_path() ? name_path.parent_path().filename().string()
                                         : name_path.stem().string();
    r.source = fmt::format("{}: image {} ('{}')", (dir / "images.txt").string(), image->image_id,
                           image->image_name);
    auto [previous, fresh] = by_name.emplace(r.name, image->image_name);
    if (!fresh) {
      throw InputError(fmt::format("{}: images '{}' and '{}' are both camera '{}': select one "
                                   "image per camera",
                                   dir.string(), previous->second, image->image_name, r.name));
    }
    const Intrinsics& in = image->camera.intrinsics;
    r.width = in.width;
    r.height = in.height;
    r.fx = in.fx, r.fy = in.fy, r.cx = in.cx, r.cy = in.cy;
    r.colmap_pixels = true;
    r.distortion = {in.k1, in.k2, in.p1, in.p2};
    r.rotation = image->camera.camera_from_world.linear();
    r.translation = image->camera.camera_from_world.translation();
    out.cameras.push_back(std::move(r));
  }
  return out;
}

// --- OpenCV FileStorage ------------------------------------------------------------------------

namespace {

// Numbers of a FileStorage node: an !!opencv-matrix, a sequence (nested or flat) or a number.
bool opencv_numbers(const cv::FileNode& node, std::vector<double>* out) {
  out->clear();
  if (node.empty() || node.isNone()) return false;
  if (node.isMap()) {
    cv::Mat m;
    node >> m;
    if (m.empty()) return false;
    m.convertTo(m, CV_64F);
    m = m.reshape(1, 1);
    out->assign(m.begin<double>(), m.end<double>());
    return true;
  }
  if (node.isSeq()) {
    for (const cv::FileNode& item : node) {
      std::vector<double> inner;
      if (item.isSeq()) {
        if (!opencv_numbers(item, &inner)) return false;
        out->insert(out->end(), inner.begin(), inner.end());
      } else if (item.isReal() || item.isInt()) {
        out->push_back(static_cast<double>(item));
      } else {
        return false;
      }
    }
    return true;
  }
  if (node.isReal() || node.isInt()) {
    out->push_back(static_cast<double>(node));
    return true;
  }
  return false;
}

struct OpenCvFile {
  fs::path path;
  cv::FileStorage storage;
};

// A camera's fields in FileStorage: looked up by the first of several names in a map node, or
// (names layout) as <prefix>_<camera> at the top of any of the files.
class OpenCvFields {
 public:
  // One camera's own node.
  OpenCvFields(const fs::path& file, cv::FileNode node, std::string where)
      : where_(std::move(where)) {
    nodes_.push_back({file, node});
  }
  // The names layout: top-level keys with a _<camera> suffix in any of the files.
  OpenCvFields(const std::vector<OpenCvFile>& files, std::string camera) : camera_(std::move(camera)) {
    for (const auto& f : files) nodes_.push_back({f.path, f.storage.root()});
    where_ = fmt::format("camera '{}'", camera_);
  }

  // Numbers of the first field present among `keys`; empty when none is.
  std::vector<double> numbers(std::initializer_list<const char*> keys, bool required,
                              std::string* found_key = nullptr) const {
    for (const char* key : keys) {
      for (const auto& [file, node] : nodes_) {
        const std::string name = camera_.empty() ? key : fmt::format("{}_{}", key, camera_);
        cv::FileNode field = node[name];
        if (field.empty() || field.isNone()) continue;
        std::vector<double> v;
        if (!opencv_numbers(field, &v)) {
          throw InputError(fmt::format("{}: {}: field '{}' is not a number or a matrix of numbers",
                                       file.string(), where_, name));
        }
        if (found_key) *found_key = key;
        return v;
      }
    }
    if (required) {
      std::string names;
      for (const char* key : keys) {
        names += fmt::format("{}{}{}", names.empty() ? "" : ", ", key, camera_.empty() ? "" : "_" + camera_);
      }
      throw InputError(fmt::format("{}: {}: missing field ({})", files_text(), where_, names));
    }
    return {};
  }

  std::optional<std::string> text(std::initializer_list<const char*> keys) const {
    for (const char* key : keys) {
      for (const auto& [file, node] : nodes_) {
        const std::string name = camera_.empty() ? key : fmt::format("{}_{}", key, camera_);
        cv::FileNode field = node[name];
        if (field.isString()) return static_cast<std::string>(field);
      }
    }
    return std::nullopt;
  }

  std::string files_text() const {
    std::string s;
    for (const auto& [file, node] : nodes_) s += (s.empty() ? "" : " + ") + file.string();
    return s;
  }
  const std::string& where() const { return where_; }

 private:
  std::vector<std::pair<fs::path, cv::FileNode>> nodes_;
  std::string camera_;  // names layout
  std::string where_;
};

double single(const std::vector<double>& v, const std::string& what) {
  if (v.size() != 1) throw InputError(fmt::format("{}: expected one number, found {}", what, v.size()));
  return v[0];
}

CameraRecord opencv_record(const OpenCvFields& f, const std::string& name) {
  CameraRecord r;
  r.name = name;
  r.source = fmt::format("{}: {}", f.files_text(), f.where());
  const std::string where = r.source;
  const std::vector<double> k = f.numbers({"K", "camera_matrix", "cameraMatrix", "intrinsics"}, true);
  if (k.size() != 9) throw InputError(fmt::format("{}: K has {} numbers, not 9 (3x3)", where, k.size()));
  r.fx = k[0], r.cx = k[2], r.fy = k[4], r.cy = k[5];
  r.distortion = f.numbers({"dist", "distortion_coefficients", "distCoeffs", "D", "distortion"}, false);
  std::string rotation_key;
  std::vector<double> rot = f.numbers({"Rot", "R", "rotation", "rvec"}, true, &rotation_key);
  r.rotation = rotation_from(rot, fmt::format("{}: {}", where, rotation_key));
  r.translation = vector3_from(f.numbers({"T", "t", "tvec", "translation"}, true), where + ": t");
  std::vector<double> size = f.numbers({"image_size", "imageSize", "size"}, false);
  if (size.size() == 2) {
    r.width = static_cast<int>(size[0]), r.height = static_cast<int>(size[1]);
  } else {
    r.width = static_cast<int>(single(f.numbers({"image_width", "width", "W"}, true), where + ": width"));
    r.height = static_cast<int>(single(f.numbers({"image_height", "height", "H"}, true), where + ": height"));
  }
  if (auto unit = f.text({"units", "unit"})) r.unit = parse_length_unit(*unit, where + ": units");
  return r;
}

}  // namespace

CalibrationRecords read_opencv_calibration(const std::vector<fs::path>& paths) {
  if (paths.empty()) throw InputError("OpenCV calibration: no file given");
  std::vector<OpenCvFile> files;
  for (const fs::path& path : paths) {
    if (!fs::is_regular_file(path)) throw IoError(fmt::format("{}: no such file", path.string()));
    OpenCvFile f{path, {}};
    try {
      f.storage.open(path.string(), cv::FileStorage::READ);
    } catch (const cv::Exception& e) {
      throw InputError(fmt::format("{}: not a valid OpenCV FileStorage file: {}", path.string(), e.msg));
    }
    if (!f.storage.isOpened()) {
      throw InputError(fmt::format("{}: not a valid OpenCV FileStorage file", path.string()));
    }
    files.push_back(std::move(f));
  }
  CalibrationRecords out;
  out.convention = "OpenCV FileStorage: x_cam = R x_world + t, pixel centres at integers";
  try {
    // The names layout: a "names" list in any file.
    for (const OpenCvFile& f : files) {
      cv::FileNode names = f.storage["names"];
      if (!names.isSeq()) continue;
      for (const cv::FileNode& name : names) {
        if (!name.isString()) {
          throw InputError(fmt::format("{}: names: expected a list of camera names", f.path.string()));
        }
        out.cameras.push_back(opencv_record(OpenCvFields(files, std::string(name)), std::string(name)));
      }
      return out;
    }
    for (const OpenCvFile& f : files) {
      cv::FileNode root = f.storage.root();
      bool any_node = false;
      for (const cv::FileNode& node : root) {
        const std::string key = node.name();
        if (key.rfind("camera_", 0) != 0 || !node.isMap()) continue;
        if (key == "camera_matrix") continue;
        any_node = true;
        std::string name = key.substr(7);
        if (node["name"].isString()) name = std::string(node["name"]);
        out.cameras.push_back(opencv_record(OpenCvFields(f.path, node, "node " + key), name));
      }
      if (any_node) continue;
      // One camera per file, named by camera_name/name or the file name.
      std::string name = f.path.stem().string();
      for (const char* key : {"camera_name", "name"}) {
        if (root[key].isString()) name = std::string(root[key]);
      }
      out.cameras.push_back(opencv_record(OpenCvFields(f.path, root, "top level"), name));
    }
  } catch (const cv::Exception& e) {
    throw InputError(fmt::format("OpenCV calibration: {}", e.msg));
  }
  return out;
}

namespace {

cv::Mat cv_matrix(const Eigen::MatrixXd& m) {
  cv::Mat out(static_cast<int>(m.rows()), static_cast<int>(m.cols()), CV_64F);
  for (int r = 0; r < m.rows(); ++r) {
    for (int c = 0; c < m.cols(); ++c) out.at<double>(r, c) = m(r, c);
  }
  return out;
}

Eigen::Matrix3d k_matrix(const FileCamera& f) {
  Eigen::Matrix3d k;
  k << f.fx, 0, f.cx, 0, f.fy, f.cy, 0, 0, 1;
  return k;
}

Eigen::RowVectorXd dist_row(const FileCamera& f) {
  Eigen::RowVectorXd d(static_cast<Eigen::Index>(f.distortion.size()));
  for (std::size_t i = 0; i < f.distortion.size(); ++i) d[static_cast<Eigen::Index>(i)] = f.distortion[i];
  return d;
}

void write_opencv_camera(cv::FileStorage& fs, const Camera& c, const FileCamera& f, LengthUnit unit) {
  fs << "image_width" << c.intrinsics.width << "image_height" << c.intrinsics.height;
  fs << "camera_matrix" << cv_matrix(k_matrix(f));
  fs << "distortion_coefficients" << cv_matrix(dist_row(f));
  fs << "R" << cv_matrix(f.rotation);
  fs << "t" << cv_matrix(f.translation);
  fs << "units" << unit_name(unit);
}

// FileStorage writes to a name it chooses the format from: write the temp file with the
// target's extension, then rename.
void write_storage(const fs::path& path, const std::function<void(cv::FileStorage&)>& body) {
  ensure_directory(path.parent_path().empty() ? fs::path(".") : path.parent_path());
  const fs::path temp = temp_path_for(path);
  try {
    cv::FileStorage storage(temp.string(), cv::FileStorage::WRITE);
    if (!storage.isOpened()) throw IoError(fmt::format("{}: cannot be written", path.string()));
    body(storage);
    storage.release();
  } catch (const cv::Exception& e) {
    std::error_code ec;
    fs::remove(temp, ec);
    throw IoError(fmt::format("{}: cannot be written: {}", path.string(), e.msg));
  }
  commit_temp_file(temp, path);
}

}  // namespace

void write_opencv_calibration(const fs::path& path, const std::vector<Camera>& cameras,
                              LengthUnit unit, OpenCvLayout layout) {
  if (layout == OpenCvLayout::kFilePerCamera) {
    for (const Camera& c : cameras) {
      write_storage(path / (c.name + ".yml"), [&](cv::FileStorage& fs) {
        fs << "camera_name" << c.name;
        write_opencv_camera(fs, c, to_file_camera(c, unit), unit);
      });
    }
    return;
  }
  write_storage(path, [&](cv::FileStorage& fs) {
    fs << "units" << unit_name(unit);
    if (layout == OpenCvLayout::kCameraNodes) {
      for (const Camera& c : cameras) {
        fs << ("camera_" + c.name) << "{";
        write_opencv_camera(fs, c, to_file_camera(c, unit), unit);
        fs << "}";
      }
      return;
    }
    fs << "names" << "[";
    for (const Camera& c : cameras) fs << c.name;
    fs << "]";
    for (const Camera& c : cameras) {
      const FileCamera f = to_file_camera(c, unit);
      fs << ("K_" + c.name) << cv_matrix(k_matrix(f));
      fs << ("dist_" + c.name) << cv_matrix(dist_row(f));
      fs << ("R_" + c.name) << cv_matrix(rodrigues_vector(f.rotation));
      fs << ("Rot_" + c.name) << cv_matrix(f.rotation);
      fs << ("T_" + c.name) << cv_matrix(f.translation);
      fs << ("W_" + c.name) << c.intrinsics.width << ("H_" + c.name) << c.intrinsics.height;
    }
  });
}

// --- CSV ---------------------------------------------------------------------------------------

namespace {

std::vector<std::string> split_csv(const std::string& line) {
  std::vector<std::string> out;
  std::string field;
  std::istringstream in(line);
  while (std::getline(in, field, ',')) out.push_back(trim(field));
  if (!line.empty() && line.back() == ',') out.push_back({});
  return out;
}

}  // namespace

CalibrationRecords read_csv_calibration(const fs::path& file, const CsvOptions& options) {
  std::istringstream in(read_file(file));
  std::string line;
  int number = 0;
  std::vector<std::string> header;
  std::map<std::string, std::size_t> column;
  struct Row {
    int line;
    std::vector<std::string> fields;
  };
  std::vector<Row> rows;
  while (std::getline(in, line)) {
    ++number;
    if (!line.empty() && line.back() == '\r') line.pop_back();
    if (trim(line).empty() || trim(line)[0] == '#') continue;
    std::vector<std::string> fields = split_csv(line);
    if (header.empty()) {
      header = fields;
      for (std::size_t i = 0; i < header.size(); ++i) column[lower(header[i])] = i;
      continue;
    }
    if (fields.size() != header.size()) {
      throw InputError(fmt::format("{}:{}: {} fields, the header has {}", file.string(), number,
                                   fields.size(), header.size()));
    }
    rows.push_back({number, std::move(fields)});
  }
  if (header.empty()) throw InputError(fmt::format("{}: empty (expected a header row and one row per camera)", file.string()));
  auto find_column = [&](std::initializer_list<const char*> names, bool required) -> std::optional<std::size_t> {
    for (const char* n : names) {
      if (auto it = column.find(n); it != column.end()) return it->second;
    }
    if (required) {
      throw InputError(fmt::format("{}: the header names no column {}", file.string(), *names.begin()));
    }
    return std::nullopt;
  };
  const std::size_t c_name = *find_column({"name", "camera", "camera_name"}, true);
  const std::size_t c_w = *find_column({"width", "w"}, true), c_h = *find_column({"height", "h"}, true);
  std::vector<std::size_t> c_rot, c_t, c_k;
  for (const char* n : {"rx", "ry", "rz"}) c_rot.push_back(*find_column({n}, true));
  for (const char* n : {"tx", "ty", "tz"}) c_t.push_back(*find_column({n}, true));
  const std::size_t c_fx = *find_column({"fx"}, true), c_fy = *find_column({"fy"}, true);
  const std::size_t c_cx = *find_column({"cx", "px"}, true), c_cy = *find_column({"cy", "py"}, true);
  std::vector<std::optional<std::size_t>> c_dist;
  for (const char* n : {"k1", "k2", "p1", "p2", "k3"}) c_dist.push_back(find_column({n}, false));

  CalibrationRecords out;
  bool normalised = options.intrinsics == CsvIntrinsics::kNormalised;
  auto number_at = [&](const Row& row, std::size_t c) {
    const std::string& text = row.fields[c];
    double value = 0;
    const auto [end, ec] = std::from_chars(text.data(), text.data() + text.size(), value);
    if (ec != std::errc() || end != text.data() + text.size() || !std::isfinite(value)) {
      throw InputError(fmt::format("{}:{}: column {}: '{}' is not a finite number", file.string(),
                                   row.line, header[c], text));
    }
    return value;
  };
  if (options.intrinsics == CsvIntrinsics::kDetect && !rows.empty()) {
    normalised = number_at(rows.front(), c_fx) < 10;
  }
  for (const Row& row : rows) {
    CameraRecord r;
    r.name = row.fields[c_name];
    r.source = fmt::format("{}:{}", file.string(), row.line);
    r.width = static_cast<int>(number_at(row, c_w));
    r.height = static_cast<int>(number_at(row, c_h));
    const double fx = number_at(row, c_fx), fy = number_at(row, c_fy);
    const double cx = number_at(row, c_cx), cy = number_at(row, c_cy);
    if (options.intrinsics == CsvIntrinsics::kDetect && (fx < 10) != normalised) {
      throw InputError(fmt::format("{}:{}: fx {} and the first row's disagree on whether the "
                                   "intrinsics are normalised (say which explicitly)",
                                   file.string(), row.line, fx));
    }
    if (normalised) {  // fractions of the image from edge to edge: COLMAP's pixel convention
      r.fx = fx * r.width, r.fy = fy * r.height, r.cx = cx * r.width, r.cy = cy * r.height;
      r.colmap_pixels = true;
    } else {
      r.fx = fx, r.fy = fy, r.cx = cx, r.cy = cy;
    }
    for (const auto& c : c_dist) {
      if (c) r.distortion.push_back(number_at(row, *c));
    }
    const Eigen::Matrix3d rot = rodrigues({number_at(row, c_rot[0]), number_at(row, c_rot[1]), number_at(row, c_rot[2])});
    const Eigen::Vector3d t(number_at(row, c_t[0]), number_at(row, c_t[1]), number_at(row, c_t[2]));
    if (options.pose == CsvPose::kWorldFromCamera) {
      r.rotation = rot.transpose();
      r.translation = -(rot.transpose() * t);
    } else {
      r.rotation = rot;
      r.translation = t;
    }
    out.cameras.push_back(std::move(r));
  }
  out.convention = fmt::format(
      "CSV: axis-angle rx ry rz and tx ty tz are the {}, intrinsics {}",
      options.pose == CsvPose::kWorldFromCamera ? "camera's pose in the world (world_from_camera; t = camera centre)"
                                                : "world-to-camera transform (camera_from_world)",
      normalised ? "normalised by the image size (edge to edge)" : "in pixels (pixel centres at integers)");
  return out;
}

void write_csv_calibration(const fs::path& file, const std::vector<Camera>& cameras, LengthUnit unit,
                           bool normalised, CsvPose pose) {
  std::string out = "name,width,height,rx,ry,rz,tx,ty,tz,fx,fy,cx,cy,k1,k2,p1,p2\n";
  for (const Camera& c : cameras) {
    const FileCamera f = to_file_camera(c, unit);
    Eigen::Matrix3d rot = f.rotation;
    Eigen::Vector3d t = f.translation;
    if (pose == CsvPose::kWorldFromCamera) {
      rot = f.rotation.transpose();
      t = -(rot * f.translation);
    }
    const Eigen::Vector3d r = rodrigues_vector(rot);
    const Intrinsics& in = c.intrinsics;
    const double w = in.width, h = in.height;
    const double fx = normalised ? in.fx / w : f.fx, fy = normalised ? in.fy / h : f.fy;
    const double cx = normalised ? in.cx / w : f.cx, cy = normalised ? in.cy / h : f.cy;
    out += fmt::format("{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{}\n", c.name, in.width,
                       in.height, r.x(), r.y(), r.z(), t.x(), t.y(), t.z(), fx, fy, cx, cy, in.k1,
                       in.k2, in.p1, in.p2);
  }
  write_file_atomic(file, out);
}

// --- JSON / YAML -------------------------------------------------------------------------------

namespace {

std::string at_line(const fs::path& file, const YAML::Node& node) {
  return fmt::format("{}:{}", file.string(), node.Mark().line + 1);
}

void yaml_numbers(const fs::path& file, const YAML::Node& node, const std::string& field,
                  std::vector<double>* out) {
  if (node.IsSequence()) {
    for (const auto& item : node) yaml_numbers(file, item, field, out);
    return;
  }
  try {
    out->push_back(node.as<double>());
  } catch (const YAML::Exception&) {
    throw InputError(fmt::format("{}: {}: '{}' is not a number", at_line(file, node), field,
                                 node.IsScalar() ? node.Scalar() : std::string("(not a scalar)")));
  }
  if (!std::isfinite(out->back())) {
    throw InputError(fmt::format("{}: {}: not a finite number", at_line(file, node), field));
  }
}

// The numbers of the first of `keys` present in `camera`; empty when none is (an error when
// `required`).
std::vector<double> yaml_field(const fs::path& file, const YAML::Node& camera, const std::string& name,
                               std::initializer_list<const char*> keys, bool required,
                               std::string* found = nullptr) {
  for (const char* key : keys) {
    const YAML::Node v = camera[key];
    if (!v.IsDefined() || v.IsNull()) continue;
    std::vector<double> out;
    yaml_numbers(file, v, key, &out);
    if (found) *found = key;
    return out;
  }
  if (required) {
    std::string names;
    for (const char* key : keys) names += fmt::format("{}{}", names.empty() ? "" : ", ", key);
    throw InputError(fmt::format("{}: camera '{}': missing field ({})", at_line(file, camera), name, names));
  }
  return {};
}

std::optional<LengthUnit> yaml_unit(const fs::path& file, const YAML::Node& node) {
  for (const char* key : {"unit", "units"}) {
    const YAML::Node u = node[key];
    if (u.IsDefined() && u.IsScalar()) return parse_length_unit(u.Scalar(), at_line(file, u) + ": " + key);
  }
  return std::nullopt;
}

CameraRecord json_record(const fs::path& file, const YAML::Node& cam, const std::string& name,
                         std::optional<LengthUnit> unit) {
  if (!cam.IsMap()) throw InputError(fmt::format("{}: camera '{}': expected a mapping of fields", at_line(file, cam), name));
  CameraRecord r;
  r.name = name;
  r.source = at_line(file, cam);
  const std::string where = fmt::format("{}: camera '{}'", r.source, name);
  const std::vector<double> k = yaml_field(file, cam, name, {"K", "camera_matrix", "intrinsics", "matrix"}, false);
  if (!k.empty()) {
    if (k.size() != 9) throw InputError(fmt::format("{}: K has {} numbers, not 9 (3x3)", where, k.size()));
    r.fx = k[0], r.cx = k[2], r.fy = k[4], r.cy = k[5];
  } else {
    r.fx = yaml_field(file, cam, name, {"fx"}, true).at(0);
    r.fy = yaml_field(file, cam, name, {"fy"}, true).at(0);
    r.cx = yaml_field(file, cam, name, {"cx"}, true).at(0);
    r.cy = yaml_field(file, cam, name, {"cy"}, true).at(0);
  }
  r.distortion = yaml_field(file, cam, name, {"dist", "distCoef", "distortion", "distortions", "D"}, false);
  std::string key;
  const std::vector<double> rot = yaml_field(file, cam, name, {"R", "rotation", "rvec"}, true, &key);
  r.rotation = rotation_from(rot, fmt::format("{}: {}", where, key));
  r.translation = vector3_from(yaml_field(file, cam, name, {"t", "T", "translation", "tvec"}, true), where + ": t");
  const std::vector<double> size = yaml_field(file, cam, name, {"size", "resolution", "image_size", "imgSize"}, false);
  if (size.size() == 2) {
    r.width = static_cast<int>(size[0]), r.height = static_cast<int>(size[1]);
  } else if (!size.empty()) {
    throw InputError(fmt::format("{}: the image size has {} numbers, not 2 (width, height)", where, size.size()));
  } else {
    r.width = static_cast<int>(yaml_field(file, cam, name, {"width", "w", "image_width"}, true).at(0));
    r.height = static_cast<int>(yaml_field(file, cam, name, {"height", "h", "image_height"}, true).at(0));
  }
  r.unit = yaml_unit(file, cam);
  if (!r.unit) r.unit = unit;
  return r;
}

}  // namespace

CalibrationRecords read_json_calibration(const fs::path& file) {
  YAML::Node loaded;
  try {
    loaded = YAML::Load(read_file(file));
  } catch (const YAML::Exception& e) {
    throw InputError(fmt::format("{}:{}: not valid JSON/YAML: {}", file.string(), e.mark.line + 1, e.msg));
  }
  const YAML::Node& root = loaded;  // const: lookups must not add keys
  CalibrationRecords out;
  out.convention = "JSON/YAML: x_cam = R x_world + t, pixel centres at integers";
  std::optional<LengthUnit> unit;
  YAML::Node cameras = root;
  if (root.IsMap()) {
    unit = yaml_unit(file, root);
    if (root["cameras"].IsDefined()) cameras = root["cameras"];
  }
  if (cameras.IsSequence()) {
    for (std::size_t i = 0; i < cameras.size(); ++i) {
      const YAML::Node cam = cameras[i];
      const YAML::Node name = cam["name"];
      if (!name.IsDefined() || !name.IsScalar()) {
        throw InputError(fmt::format("{}: cameras[{}] has no \"name\"", at_line(file, cam), i));
      }
      out.cameras.push_back(json_record(file, cam, name.Scalar(), unit));
    }
  } else if (cameras.IsMap()) {
    for (const auto& kv : cameras) {
      const std::string name = kv.first.as<std::string>();
      if (kv.second.IsScalar() && (name == "unit" || name == "units")) continue;
      out.cameras.push_back(json_record(file, kv.second, name, unit));
    }
  } else {
    throw InputError(fmt::format("{}: expected an object keyed by camera name or a list of cameras", file.string()));
  }
  if (out.cameras.empty()) throw InputError(fmt::format("{}: no cameras", file.string()));
  return out;
}

void write_json_calibration(const fs::path& file, const std::vector<Camera>& cameras, LengthUnit unit,
                            bool keyed_by_name) {
  using json = nlohmann::json;
  json root = {{"unit", unit_name(unit)}};
  json list = json::array();
  for (const Camera& c : cameras) {
    const FileCamera f = to_file_camera(c, unit);
    json cam;
    if (!keyed_by_name) cam["name"] = c.name;
    cam["width"] = c.intrinsics.width;
    cam["height"] = c.intrinsics.height;
    cam["K"] = {{f.fx, 0.0, f.cx}, {0.0, f.fy, f.cy}, {0.0, 0.0, 1.0}};
    cam["dist"] = f.distortion;
    json r = json::array();
    for (int i = 0; i < 3; ++i) r.push_back({f.rotation(i, 0), f.rotation(i, 1), f.rotation(i, 2)});
    cam["R"] = r;
    cam["t"] = {f.translation.x(), f.translation.y(), f.translation.z()};
    if (keyed_by_name) {
      root[c.name] = cam;
    } else {
      list.push_back(cam);
    }
  }
  if (!keyed_by_name) root["cameras"] = list;
  write_file_atomic(file, root.dump(1) + "\n");
}

}  // namespace fourd
