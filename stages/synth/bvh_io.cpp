#include "stages/synth/bvh_io.h"

#include <fmt/format.h>

#include <Eigen/SVD>
#include <algorithm>
#include <array>
#include <charconv>
#include <cmath>
#include <numbers>
#include <sstream>

#include "pipeline/core/error.h"
#include "pipeline/core/files.h"

namespace fourd::synth {
namespace {

// our = axes * bvh for a y-up file facing +z (the glTF convention, see gltf_io.h).
Eigen::Matrix3d our_from_bvh(const BvhOptions& options) {
  if (!options.y_up) return Eigen::Matrix3d::Identity();
  return (Eigen::Matrix3d() << 0, 0, 1, 1, 0, 0, 0, 1, 0).finished();
}

void check_options(const BvhOptions& options, const std::string& file) {
  if (!(options.metres_per_unit > 0))
    throw ConfigError(
        fmt::format("{}: metres_per_unit must be positive, not {}", file, options.metres_per_unit));
}

double radians(double degrees) { return degrees * std::numbers::pi / 180; }
double degrees(double radians) { return radians * 180 / std::numbers::pi; }

// ---------------------------------------------------------------------------------------------
// Reading.

enum class ChannelKind { kPosition, kRotation };

struct Channel {
  ChannelKind kind;
  int axis;  // 0 x, 1 y, 2 z
};

// The file as lines of whitespace-separated tokens, read with a cursor that knows its line.
class Tokens {
 public:
  Tokens(std::string file, const std::string& text) : file_(std::move(file)) {
    std::istringstream in(text);
    std::string line;
    while (std::getline(in, line)) {
      std::vector<std::string> tokens;
      std::istringstream words(line);
      for (std::string w; words >> w;) tokens.push_back(w);
      lines_.push_back(std::move(tokens));
    }
  }

  // Errors name the line of the token read last (or of the next one, before any).
  [[noreturn]] void fail(const std::string& what) const { fail_at(last_line_, what); }
  [[noreturn]] void fail_at(int line, const std::string& what) const {
    throw InputError(fmt::format("{}:{}: {}", file_, line, what));
  }

  // 1-based line of the next token.
  int line_number() {
    skip_blank();
    return static_cast<int>(line_) + 1;
  }

  bool at_end() {
    skip_blank();
    return line_ >= lines_.size();
  }

  // Lines from the next token's to the end of the file: a bound on the records left.
  std::size_t lines_left() {
    skip_blank();
    return lines_.size() - line_;
  }

  std::string next(const char* expected) {
    if (at_end()) fail(fmt::format("unexpected end of file, expected {}", expected));
    last_line_ = static_cast<int>(line_) + 1;
    return lines_[line_][token_++];
  }

  void expect(const std::string& word) {
    const std::string got = next(word.c_str());
    if (got != word) fail(fmt::format("expected '{}', found '{}'", word, got));
  }

  // The rest of the current line as one string (joint names may contain spaces); a trailing
  // "{" is left to be read as a token.
  std::string rest_of_line(const char* expected) {
    const std::vector<std::string>& tokens = lines_[line_];
    std::size_t end = tokens.size();
    if (end > token_ && tokens[end - 1] == "{") --end;
    std::string text;
    for (std::size_t i = token_; i < end; ++i) text += (text.empty() ? "" : " ") + tokens[i];
    if (text.empty()) fail(fmt::format("expected {}", expected));
    token_ = end;
    return text;
  }

  double number(const char* expected) {
    const std::string token = next(expected);
    return parse_number(token, expected);
  }

  double parse_number(const std::string& token, const char* expected) const {
    const char* begin = token.data() + (token.starts_with('+') ? 1 : 0);
    const char* end = token.data() + token.size();
    double value = 0;
    const auto [ptr, ec] = std::from_chars(begin, end, value);
    if (ec != std::errc() || ptr != end || !std::isfinite(value))
      fail(fmt::format("expected {}, found '{}'", expected, token));
    return value;
  }

  // The remaining tokens of the current line, moving to the next line.
  const std::vector<std::string>& whole_line() {
    skip_blank();
    const std::vector<std::string>& tokens = lines_[line_];
    last_line_ = static_cast<int>(line_) + 1;
    ++line_;
    token_ = 0;
    return tokens;
  }

  // Positions the cursor at the start of the line after the current one.
  void finish_line() {
    if (line_ < lines_.size() && token_ > 0) {
      if (token_ < lines_[line_].size())
        fail(fmt::format("unexpected '{}' at the end of the line", lines_[line_][token_]));
      ++line_;
      token_ = 0;
    }
  }

 private:
  void skip_blank() {
    while (line_ < lines_.size() && token_ >= lines_[line_].size()) {
      ++line_;
      token_ = 0;
    }
  }

  std::string file_;
  std::vector<std::vector<std::string>> lines_;
  std::size_t line_ = 0, token_ = 0;
  int last_line_ = 1;
};

struct RawJoint {
  std::string name;
  int parent = -1;
  Eigen::Vector3d offset = Eigen::Vector3d::Zero();  // file units and axes
  std::vector<std::string> channel_names;
  std::vector<Channel> channels;
};

class BvhParser {
 public:
  BvhParser(const std::string& file, const std::string& text) : tokens_(file, text) {}

  void parse(std::vector<RawJoint>& joints, std::vector<std::pair<int, Eigen::Vector3d>>& ends,
             std::vector<std::vector<double>>& frames, double& frame_time) {
    tokens_.expect("HIERARCHY");
    tokens_.expect("ROOT");
    parse_joint(joints, ends, -1);
    std::string word = tokens_.next("MOTION");
    if (word == "ROOT") tokens_.fail("more than one ROOT; only one hierarchy is supported");
    if (word != "MOTION") tokens_.fail(fmt::format("expected 'MOTION', found '{}'", word));
    tokens_.expect("Frames:");
    const double n = tokens_.number("the number of frames");
    if (n < 1 || n != std::floor(n)) tokens_.fail(fmt::format("invalid frame count {}", n));
    tokens_.expect("Frame");
    tokens_.expect("Time:");
    frame_time = tokens_.number("the frame time in seconds");
    if (!(frame_time > 0))
      tokens_.fail(fmt::format("frame time must be positive, not {}", frame_time));
    tokens_.finish_line();

    std::size_t channels = 0;
    for (const RawJoint& j : joints) channels += j.channels.size();
    if (channels == 0) tokens_.fail("the hierarchy has no channels");
    const auto count = static_cast<std::size_t>(std::min(n, 1e15));  // more than any file holds
    frames.reserve(std::min<std::size_t>(count, tokens_.lines_left()));
    for (std::size_t f = 0; f < count; ++f) {
      if (tokens_.at_end())
        tokens_.fail(fmt::format("the file ends after {} of the {} frames it declares", f, count));
      const int line = tokens_.line_number();
      const std::vector<std::string>& values = tokens_.whole_line();
      if (values.size() != channels)
        tokens_.fail_at(line, fmt::format("frame {} has {} values, the hierarchy has {} channels",
                                          f, values.size(), channels));
      std::vector<double> frame(channels);
      for (std::size_t c = 0; c < channels; ++c)
        frame[c] = tokens_.parse_number(values[c], "a channel value");
      frames.push_back(std::move(frame));
    }
    if (!tokens_.at_end())
      tokens_.fail(fmt::format("more frame lines than the {} declared by 'Frames:'", count));
  }

 private:
  // After ROOT or JOINT: name { OFFSET x y z CHANNELS n ... children }.
  void parse_joint(std::vector<RawJoint>& joints,
                   std::vector<std::pair<int, Eigen::Vector3d>>& ends, int parent) {
    RawJoint joint;
    joint.parent = parent;
    joint.name = tokens_.rest_of_line("a joint name");
    for (const RawJoint& j : joints)
      if (j.name == joint.name)
        tokens_.fail(fmt::format("joint '{}' is defined twice", joint.name));
    tokens_.expect("{");
    tokens_.expect("OFFSET");
    for (int c = 0; c < 3; ++c) joint.offset[c] = tokens_.number("an OFFSET coordinate");
    tokens_.expect("CHANNELS");
    const double n = tokens_.number("the number of channels");
    if (n < 0 || n > 6 || n != std::floor(n))
      tokens_.fail(fmt::format("joint '{}': invalid channel count {}", joint.name, n));
    for (int c = 0; c < static_cast<int>(n); ++c) {
      const std::string name = tokens_.next("a channel name");
      joint.channels.push_back(parse_channel(name));
      joint.channel_names.push_back(name);
    }
    const int index = static_cast<int>(joints.size());
    joints.push_back(std::move(joint));
    bool has_children = false;
    for (;;) {
      const std::string word = tokens_.next("JOINT, End Site or '}'");
      if (word == "}") break;
      if (word == "JOINT") {
        parse_joint(joints, ends, index);
      } else if (word == "End") {
        tokens_.expect("Site");
        tokens_.expect("{");
        tokens_.expect("OFFSET");
        Eigen::Vector3d offset;
        for (int c = 0; c < 3; ++c) offset[c] = tokens_.number("an OFFSET coordinate");
        tokens_.expect("}");
        ends.emplace_back(index, offset);
      } else {
        tokens_.fail(fmt::format("expected JOINT, End Site or '}}' in joint '{}', found '{}'",
                                 joints[index].name, word));
      }
      has_children = true;
    }
    if (!has_children)
      tokens_.fail(
          fmt::format("joint '{}' has neither children nor an End Site", joints[index].name));
  }

  Channel parse_channel(const std::string& name) {
    std::string lower = name;
    std::transform(lower.begin(), lower.end(), lower.begin(),
                   [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
    if (lower.size() == 9 && lower.substr(1) == "position" && lower[0] >= 'x' && lower[0] <= 'z')
      return {ChannelKind::kPosition, lower[0] - 'x'};
    if (lower.size() == 9 && lower.substr(1) == "rotation" && lower[0] >= 'x' && lower[0] <= 'z')
      return {ChannelKind::kRotation, lower[0] - 'x'};
    tokens_.fail(fmt::format("unknown channel '{}' (expected X/Y/Z position or rotation)", name));
  }

  Tokens tokens_;
};

// ---------------------------------------------------------------------------------------------
// Writing.

// R = Rz(z) * Rx(x) * Ry(y), the order of the channels we write. Angles in radians.
Eigen::Vector3d zxy_angles(const Eigen::Matrix3d& r) {
  const double sx = std::clamp(r(2, 1), -1.0, 1.0);
  const double x = std::asin(sx);
  double z, y;
  if (std::abs(sx) < 1 - 1e-12) {
    z = std::atan2(-r(0, 1), r(1, 1));
    y = std::atan2(-r(2, 0), r(2, 2));
  } else {  // gimbal lock: only z + y (or z - y) is defined; put it all in z
    z = std::atan2(r(1, 0), r(0, 0));
    y = 0;
  }
  return {z, x, y};
}

// Adds whole turns to `angle` to bring it nearest to `previous` (smooth curves in editors).
double unwrap_degrees(double angle, double previous) {
  return angle + 360 * std::round((previous - angle) / 360);
}

void write_joint(std::ostream& out, const Skeleton& skeleton,
                 const std::vector<std::vector<int>>& children, int j, int depth,
                 const Eigen::Matrix3d& bvh_from_our, double units, std::vector<int>& order) {
  const std::string indent(depth, '\t');
  order.push_back(j);
  const Eigen::Vector3d offset = bvh_from_our * skeleton.rest_offsets[j] / units;
  out << indent << (j == 0 ? "ROOT " : "JOINT ") << skeleton.names[j] << "\n" << indent << "{\n";
  out << fmt::format("{}\tOFFSET {:.6f} {:.6f} {:.6f}\n", indent, offset.x(), offset.y(),
                     offset.z());
  out << indent
      << (j == 0 ? "\tCHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation Yrotation\n"
                 : "\tCHANNELS 3 Zrotation Xrotation Yrotation\n");
  for (int c : children[j])
    write_joint(out, skeleton, children, c, depth + 1, bvh_from_our, units, order);
  if (children[j].empty())  // BVH needs an end; our skeleton has no leaf length to give it
    out << indent << "\tEnd Site\n"
        << indent << "\t{\n"
        << indent << "\t\tOFFSET 0 0 0\n"
        << indent << "\t}\n";
  out << indent << "}\n";
}

// ---------------------------------------------------------------------------------------------
// Retargeting.

std::vector<Eigen::Vector3d> rest_positions(const Skeleton& skeleton) {
  std::vector<Eigen::Vector3d> p(skeleton.size());
  for (std::size_t j = 0; j < skeleton.size(); ++j)
    p[j] = skeleton.parents[j] < 0
               ? skeleton.rest_offsets[j]
               : Eigen::Vector3d(p[skeleton.parents[j]] + skeleton.rest_offsets[j]);
  return p;
}

bool is_descendant(const Skeleton& skeleton, int joint, int ancestor) {
  for (int j = skeleton.parents[joint]; j >= 0; j = skeleton.parents[j])
    if (j == ancestor) return true;
  return false;
}

// The rotation turning the unit directions `from` onto `to` as well as possible: the shortest
// arc for one direction (or several parallel ones), else the least-squares fit (Kabsch).
Eigen::Matrix3d align_directions(const std::vector<Eigen::Vector3d>& from,
                                 const std::vector<Eigen::Vector3d>& to) {
  if (from.empty()) return Eigen::Matrix3d::Identity();
  Eigen::Matrix3d h = Eigen::Matrix3d::Zero();
  for (std::size_t i = 0; i < from.size(); ++i) h += from[i] * to[i].transpose();
  Eigen::JacobiSVD<Eigen::Matrix3d> svd(h, Eigen::ComputeFullU | Eigen::ComputeFullV);
  if (from.size() == 1 || svd.singularValues()[1] < 1e-6 * svd.singularValues()[0])
    return Eigen::Quaterniond::FromTwoVectors(from[0], to[0]).toRotationMatrix();
  Eigen::Matrix3d d = Eigen::Matrix3d::Identity();
  d(2, 2) = (svd.matrixV() * svd.matrixU().transpose()).determinant() < 0 ? -1 : 1;
  return svd.matrixV() * d * svd.matrixU().transpose();
}

}  // namespace

BvhMotion read_bvh(const fs::path& path, const BvhOptions& options) {
  const std::string file = path.string();
  check_options(options, file);
  std::vector<RawJoint> joints;
  std::vector<std::pair<int, Eigen::Vector3d>> ends;
  std::vector<std::vector<double>> frames;
  BvhMotion motion;
  motion.source = file;
  BvhParser(file, read_file(path)).parse(joints, ends, frames, motion.frame_time);

  const Eigen::Matrix3d axes = our_from_bvh(options);
  const Eigen::Quaterniond axes_q(axes);
  const double scale = options.metres_per_unit;
  for (const RawJoint& j : joints) {
    motion.skeleton.names.push_back(j.name);
    motion.skeleton.parents.push_back(j.parent);
    motion.skeleton.rest_offsets.push_back(axes * j.offset * scale);
    motion.channels.push_back(j.channel_names);
  }
  for (const auto& [joint, offset] : ends)
    motion.end_sites.emplace_back(joint, axes * offset * scale);

  motion.frames.resize(frames.size());
  for (std::size_t f = 0; f < frames.size(); ++f) {
    Pose& pose = motion.frames[f];
    pose.local_rotations.resize(joints.size());
    std::size_t v = 0;
    for (std::size_t j = 0; j < joints.size(); ++j) {
      Eigen::Vector3d position = joints[j].offset;
      Eigen::Quaterniond rotation = Eigen::Quaterniond::Identity();
      for (const Channel& c : joints[j].channels) {
        const double value = frames[f][v++];
        if (c.kind == ChannelKind::kPosition)
          position[c.axis] = value;
        else  // channels compose in the order listed (intrinsic rotations)
          rotation = rotation * Eigen::AngleAxisd(radians(value), Eigen::Vector3d::Unit(c.axis));
      }
      pose.local_rotations[j] = (axes_q * rotation * axes_q.conjugate()).normalized();
      if (j == 0) pose.root_position = axes * position * scale;
    }
  }
  return motion;
}

void write_bvh(const fs::path& path, const Skeleton& skeleton, const std::vector<Pose>& poses,
               double fps, const BvhOptions& options) {
  const std::string file = path.string();
  check_options(options, file);
  const std::size_t n = skeleton.size();
  if (n == 0 || skeleton.parents.size() != n || skeleton.rest_offsets.size() != n)
    throw InputError(fmt::format("{}: empty skeleton or skeleton arrays of different sizes", file));
  for (std::size_t j = 0; j < n; ++j) {
    const int parent = skeleton.parents[j];
    if (j == 0 ? parent != -1 : (parent < 0 || parent >= static_cast<int>(j)))
      throw InputError(fmt::format("{}: joint '{}' has parent {}, not in topological order", file,
                                   skeleton.names[j], parent));
    if (skeleton.names[j].empty() ||
        skeleton.names[j].find_first_of(" \t\r\n{}") != std::string::npos)
      throw InputError(
          fmt::format("{}: joint name '{}' cannot be written to BVH", file, skeleton.names[j]));
  }
  if (poses.empty() || !(fps > 0))
    throw InputError(fmt::format("{}: no poses to write or frame rate {} not positive", file, fps));
  for (std::size_t f = 0; f < poses.size(); ++f)
    if (poses[f].local_rotations.size() != n)
      throw InputError(fmt::format("{}: pose {} has {} joint rotations, the skeleton {} joints",
                                   file, f, poses[f].local_rotations.size(), n));

  const Eigen::Matrix3d bvh_from_our = our_from_bvh(options).transpose();
  const double units = options.metres_per_unit;
  std::vector<std::vector<int>> children(n);
  for (std::size_t j = 1; j < n; ++j) children[skeleton.parents[j]].push_back(static_cast<int>(j));

  std::ostringstream out;
  std::vector<int> order;  // file order of the joints (depth first)
  out << "HIERARCHY\n";
  write_joint(out, skeleton, children, 0, 0, bvh_from_our, units, order);
  out << "MOTION\n"
      << "Frames: " << poses.size() << "\n"
      << fmt::format("Frame Time: {:.10f}\n", 1 / fps);
  std::vector<Eigen::Vector3d> previous(n, Eigen::Vector3d::Zero());
  for (std::size_t f = 0; f < poses.size(); ++f) {
    const Pose& pose = poses[f];
    const Eigen::Vector3d root = bvh_from_our * pose.root_position / units;
    std::string line = fmt::format("{:.6f} {:.6f} {:.6f}", root.x(), root.y(), root.z());
    for (int j : order) {
      const Eigen::Matrix3d r = bvh_from_our *
                                pose.local_rotations[j].normalized().toRotationMatrix() *
                                bvh_from_our.transpose();
      Eigen::Vector3d angles = zxy_angles(r);
      for (int c = 0; c < 3; ++c) {
        angles[c] = degrees(angles[c]);
        if (f > 0) angles[c] = unwrap_degrees(angles[c], previous[j][c]);
      }
      previous[j] = angles;
      line += fmt::format(" {:.6f} {:.6f} {:.6f}", angles[0], angles[1], angles[2]);
    }
    out << line << "\n";
  }
  write_file_atomic(path, out.str());
}

std::map<std::string, std::string> default_bvh_joint_map() {
  std::map<std::string, std::string> map;
  auto add = [&](const std::string& target, const std::vector<std::string>& sources) {
    for (const std::string& s : sources) map[s] = target;
  };
  add("pelvis", {"Hips", "hips", "Hip", "hip", "Pelvis", "pelvis"});
  add("spine", {"LowerBack", "Spine", "spine", "Abdomen", "abdomen"});
  // Several of these in one file: the deepest present wins (see retarget_bvh).
  add("chest", {"Spine1", "Spine2", "Spine3", "Chest", "chest", "Chest2", "chest2", "UpperChest"});
  add("neck", {"Neck", "neck", "Neck1", "neck1"});
  add("head", {"Head", "head"});
  // Full side names (CMU, Mixamo, MotionBuilder) and Poser/DAZ short ones ("lShldr").
  for (const auto& [side, full, brief] : {std::array<std::string, 3>{"_l", "Left", "l"},
                                          std::array<std::string, 3>{"_r", "Right", "r"}}) {
    add("clavicle" + side,
        {full + "Shoulder", full + "Collar", full + "Clavicle", brief + "Collar"});
    add("upper_arm" + side, {full + "Arm", full + "UpArm", full + "UpperArm", brief + "Shldr"});
    add("forearm" + side,
        {full + "ForeArm", full + "LowArm", full + "LowerArm", full + "Elbow", brief + "ForeArm"});
    add("hand" + side, {full + "Hand", full + "Wrist", brief + "Hand"});
    add("thigh" + side,
        {full + "UpLeg", full + "UpperLeg", full + "Thigh", full + "Hip", brief + "Thigh"});
    add("shin" + side, {full + "Leg", full + "LowLeg", full + "LowerLeg", full + "Shin",
                        full + "Knee", brief + "Shin"});
    add("foot" + side, {full + "Foot", full + "Ankle", brief + "Foot"});
    add("toe" + side, {full + "ToeBase", full + "Toe", full + "Toes", brief + "Toe"});
  }
  return map;
}

std::vector<Pose> retarget_bvh(const BvhMotion& motion, const Skeleton& target,
                               const std::map<std::string, std::string>& joint_map) {
  const Skeleton& source = motion.skeleton;
  // Source joints by name, and by name without a "namespace:" prefix (Mixamo's "mixamorig:").
  std::map<std::string, int> by_name;
  for (std::size_t j = 0; j < source.size(); ++j) by_name[source.names[j]] = static_cast<int>(j);
  for (std::size_t j = 0; j < source.size(); ++j) {
    const std::string& name = source.names[j];
    if (const auto colon = name.rfind(':'); colon != std::string::npos)
      by_name.emplace(name.substr(colon + 1), static_cast<int>(j));
  }
  std::vector<int> depth(source.size(), 0);
  for (std::size_t j = 1; j < source.size(); ++j) depth[j] = depth[source.parents[j]] + 1;

  std::vector<int> source_of(target.size(), -1);
  for (const auto& [source_name, target_name] : joint_map) {
    const auto s = by_name.find(source_name);
    const int t = target.find(target_name);
    if (s == by_name.end() || t < 0) continue;
    if (source_of[t] < 0 || depth[s->second] > depth[source_of[t]]) source_of[t] = s->second;
  }
  if (source_of[0] < 0)
    throw InputError(fmt::format(
        "{}: no joint of the BVH maps to the target root '{}'; the joint map must name the "
        "source joint for it (e.g. Hips)",
        motion.source, target.names[0]));

  const std::vector<Eigen::Vector3d> ps = rest_positions(source), pt = rest_positions(target);
  // The nearest mapped target ancestor of each target joint.
  std::vector<int> mapped_parent(target.size(), -1);
  for (std::size_t k = 1; k < target.size(); ++k) {
    int a = target.parents[k];
    while (a >= 0 && source_of[a] < 0) a = target.parents[a];
    mapped_parent[k] = a;
  }
  // Rest alignment per mapped target joint: its rest bones (towards its mapped children) turned
  // onto the corresponding source bones.
  std::vector<Eigen::Matrix3d> align(target.size(), Eigen::Matrix3d::Identity());
  for (std::size_t t = 0; t < target.size(); ++t) {
    if (source_of[t] < 0) continue;
    std::vector<Eigen::Vector3d> from, to;
    for (std::size_t k = 1; k < target.size(); ++k) {
      if (mapped_parent[k] != static_cast<int>(t) || source_of[k] < 0 ||
          !is_descendant(source, source_of[k], source_of[t]))
        continue;
      const Eigen::Vector3d dt = pt[k] - pt[t], ds = ps[source_of[k]] - ps[source_of[t]];
      if (dt.norm() < 1e-6 || ds.norm() < 1e-6) continue;
      from.push_back(dt.normalized());
      to.push_back(ds.normalized());
    }
    align[t] = align_directions(from, to);
  }
  // Leg-length ratio: the root's height above the lowest mapped joint, target over source.
  double ratio = 1;
  int lowest = -1;
  for (std::size_t k = 1; k < target.size(); ++k)
    if (source_of[k] >= 0 && is_descendant(source, source_of[k], source_of[0]) &&
        (lowest < 0 || pt[k].z() < pt[lowest].z()))
      lowest = static_cast<int>(k);
  if (lowest >= 0) {
    const double drop_t = pt[0].z() - pt[lowest].z();
    const double drop_s = ps[source_of[0]].z() - ps[source_of[lowest]].z();
    if (drop_t > 1e-6 && drop_s > 1e-6) ratio = drop_t / drop_s;
  }

  std::vector<Pose> out(motion.frames.size());
  std::vector<Eigen::Matrix3d> world(target.size());
  for (std::size_t f = 0; f < motion.frames.size(); ++f) {
    const Pose& frame = motion.frames[f];
    if (frame.local_rotations.size() != source.size())
      throw InputError(fmt::format("{}: frame {} has {} rotations for {} joints", motion.source, f,
                                   frame.local_rotations.size(), source.size()));
    const std::vector<Eigen::Isometry3d> source_world = forward_kinematics(source, frame);
    Pose& pose = out[f];
    pose.local_rotations.resize(target.size());
    for (std::size_t t = 0; t < target.size(); ++t) {
      const int parent = target.parents[t];
      if (source_of[t] >= 0)
        world[t] = source_world[source_of[t]].linear() * align[t];
      else
        world[t] = world[parent];
      const Eigen::Matrix3d local =
          parent < 0 ? world[t] : Eigen::Matrix3d(world[parent].transpose() * world[t]);
      pose.local_rotations[t] = Eigen::Quaterniond(local).normalized();
    }
    pose.root_position = ratio * source_world[source_of[0]].translation();
  }
  return out;
}

}  // namespace fourd::synth
