#pragma once
// Options structs and their YAML mapping.
//
// Every options struct declares its fields once, in a visit() member:
//
//   struct RigOptions {
//     int count = 8;          // number of cameras
//     double radius = 3.0;    // circle radius [m]
//     template <class V> void visit(V& v) {
//       v("count", count, "number of cameras", Range{1, 256});
//       v("radius", radius, "circle radius [m]", Range{0.5, 50});
//     }
//     void check() const {}   // optional cross-field checks, throw ConfigError
//   };
//
// read_options() maps a YAML node onto it (unknown keys and out-of-range values are errors
// naming the file, line, key path and the accepted values); to_yaml() writes the options a
// stage actually used. Fields may be bool, int, double, std::string, std::vector of those,
// another options struct, a std::vector of options structs, or a raw YAML::Node section.
//
// Subject-relative lengths. A length whose right value depends on the size of what is filmed
// (voxel sizes, depth ranges, thresholds in metres) declares it with Length{lo, hi} in place
// of Range{lo, hi}:
//
//       v("voxel_size", voxel_size, "fine voxel size [m]", Length{1e-5, 0.1});
//
// Its in-class default is the value for the reference subject (kReferenceSubjectSize, the
// 1.75 m person the defaults were tuned on). A stage that knows the size of its subject calls
// scale_unset_lengths(options, factor, set_keys, path), which multiplies every such length the
// user did not set (read_options records the keys a session.yaml or preset set) by
// factor = subject size / kReferenceSubjectSize; a length set explicitly is kept as given.
//
// Tuned values. A struct member that is not an option (no v() line: session.yaml cannot set it,
// `fourd defaults` does not print it) but is a subject-relative length is still scaled when the
// struct lists it in an internal_lengths() member, with the same visitor signature:
//
//     template <class V>
//     void internal_lengths(V& v) {
//       v("coarse_voxel", coarse_voxel, "", Length{1e-4, 0.5});
//       v("descriptor", descriptor, "");  // a nested struct: its own lengths
//     }
//
// Only the scaling visits it; a nested struct reached from visit() or internal_lengths() has
// its own internal_lengths() visited too.
#include <yaml-cpp/yaml.h>

#include <filesystem>
#include <fmt/format.h>
#include <limits>
#include <optional>
#include <set>
#include <string>
#include <type_traits>
#include <vector>

#include "pipeline/core/error.h"

namespace fourd {

struct Range {
  double lo = -std::numeric_limits<double>::infinity();
  double hi = std::numeric_limits<double>::infinity();
  // A length [m] whose default is for the reference subject and is scaled to the capture's
  // (see Length and scale_unset_lengths).
  bool subject_length = false;
};

// Range of a subject-relative length [m] (see above): lo..hi are the values a user may set.
struct Length : Range {
  constexpr Length(double lo_ = 0, double hi_ = std::numeric_limits<double>::infinity())
      : Range{lo_, hi_, true} {}
};

// Size of the subject the defaults of subject-relative lengths are tuned for: the largest
// extent of a 1.75 m tall person standing [m].
inline constexpr double kReferenceSubjectSize = 1.75;

// Full key paths ("stages.reconstruct.depth.step") that a read set explicitly.
using SetKeys = std::set<std::string>;

namespace config_detail {

template <class T, class = void>
struct is_options : std::false_type {};
struct NullVisitor {
  template <class U, class... Rest>
  void operator()(const char*, U&, Rest&&...) {}
};
template <class T>
struct is_options<T, std::void_t<decltype(std::declval<T&>().visit(std::declval<NullVisitor&>()))>>
    : std::true_type {};

// A struct with tuned lengths that are not options (see "Tuned values" above).
template <class T, class = void>
struct has_internal_lengths : std::false_type {};
template <class T>
struct has_internal_lengths<
    T, std::void_t<decltype(std::declval<T&>().internal_lengths(std::declval<NullVisitor&>()))>>
    : std::true_type {};

template <class T>
struct is_vector : std::false_type {};
template <class T, class A>
struct is_vector<std::vector<T, A>> : std::true_type {};

std::string location(const std::string& file, const YAML::Node& node);
[[noreturn]] void fail(const std::string& file, const YAML::Node& node, const std::string& path,
                       const std::string& message);

template <class T>
void call_check(const T& opts, const std::string& path) {
  if constexpr (requires { opts.check(); }) {
    try {
      opts.check();
    } catch (const ConfigError& e) {
      throw ConfigError(path.empty() ? e.what() : fmt::format("{}: {}", path, e.what()));
    }
  }
}

template <class T>
void read_value(const std::string& file, const YAML::Node& node, const std::string& path, T& out,
                const Range& range, SetKeys* set_keys);

class Reader {
 public:
  Reader(const std::string& file, const YAML::Node& node, std::string path, SetKeys* set_keys)
      : file_(file), node_(node), path_(std::move(path)), set_keys_(set_keys) {}

  template <class T>
  void operator()(const char* key, T& field, const char* /*help*/, Range range = {}) {
    known_.insert(key);
    YAML::Node child = node_[key];
    if (!child.IsDefined() || child.IsNull()) return;  // keep the default
    const std::string path = path_.empty() ? key : path_ + "." + key;
    if (set_keys_) set_keys_->insert(path);
    read_value(file_, child, path, field, range, set_keys_);
  }

  void finish() const {
    for (const auto& kv : node_) {
      if (!kv.first.IsScalar()) {  // e.g. "{a: 1}: 2" makes a map the key
        fail(file_, kv.first, path_, "a key must be a name, not a list or a map");
      }
      std::string key = kv.first.as<std::string>();
      if (!known_.count(key)) {
        std::string names;
        for (const auto& k : known_) names += (names.empty() ? "" : ", ") + k;
        fail(file_, kv.first, path_.empty() ? key : path_ + "." + key,
             fmt::format("unknown key '{}' (known keys: {})", key, names));
      }
    }
  }

 private:
  const std::string& file_;
  YAML::Node node_;
  std::string path_;
  SetKeys* set_keys_;
  std::set<std::string> known_;
};

template <class T>
void read_value(const std::string& file, const YAML::Node& node, const std::string& path, T& out,
                const Range& range, SetKeys* set_keys) {
  if constexpr (std::is_same_v<T, YAML::Node>) {
    out = node;  // a raw section, mapped later by whoever owns it
  } else if constexpr (is_options<T>::value) {
    if (!node.IsMap()) fail(file, node, path, "expected a mapping of option names to values");
    Reader reader(file, node, path, set_keys);
    out.visit(reader);
    reader.finish();
    call_check(out, path);
  } else if constexpr (is_vector<T>::value) {
    if (!node.IsSequence()) fail(file, node, path, "expected a list");
    T values;
    int i = 0;
    for (const auto& item : node) {
      typename T::value_type v{};
      read_value(file, item, fmt::format("{}[{}]", path, i++), v, range, set_keys);
      values.push_back(std::move(v));
    }
    out = std::move(values);
  } else {
    if (!node.IsScalar()) fail(file, node, path, "expected a single value");
    T v;
    try {
      v = node.as<T>();
    } catch (const YAML::Exception&) {
      const char* kind = std::is_same_v<T, bool>       ? "true or false"
                         : std::is_integral_v<T>       ? "an integer"
                         : std::is_floating_point_v<T> ? "a number"
                                                       : "a string";
      fail(file, node, path, fmt::format("'{}' is not {}", node.Scalar(), kind));
    }
    if constexpr (std::is_arithmetic_v<T> && !std::is_same_v<T, bool>) {
      if (!(static_cast<double>(v) >= range.lo && static_cast<double>(v) <= range.hi)) {
        fail(file, node, path,
             fmt::format("value {} out of range [{}, {}]", node.Scalar(), range.lo, range.hi));
      }
    }
    out = v;
  }
}

// Multiplies the subject-relative lengths (Range::subject_length) not in `set_keys` by a factor:
// the options' and the tuned ones internal_lengths() lists.
class Scaler {
 public:
  Scaler(double factor, const SetKeys& set_keys, std::string path,
         std::vector<std::string>& scaled)
      : factor_(factor), set_keys_(set_keys), path_(std::move(path)), scaled_(scaled) {}
  // Every length of `opts`, a struct at `path`.
  template <class T>
  void scale_struct(T& opts, const std::string& path) {
    Scaler inner(factor_, set_keys_, path, scaled_);
    if constexpr (is_options<T>::value) opts.visit(inner);
    if constexpr (has_internal_lengths<T>::value) opts.internal_lengths(inner);
  }
  template <class T>
  void operator()(const char* key, T& field, const char* /*help*/, Range range = {}) {
    const std::string path = path_.empty() ? key : path_ + "." + key;
    if constexpr (is_options<T>::value || has_internal_lengths<T>::value) {
      scale_struct(field, path);
    } else if constexpr (is_vector<T>::value) {
      if constexpr (is_options<typename T::value_type>::value) {
        for (std::size_t i = 0; i < field.size(); ++i) {
          scale_struct(field[i], fmt::format("{}[{}]", path, i));
        }
      } else if constexpr (std::is_floating_point_v<typename T::value_type>) {
        if (range.subject_length && !set_keys_.count(path)) {
          for (auto& v : field) v *= factor_;
          scaled_.push_back(path);
        }
      }
    } else if constexpr (std::is_floating_point_v<T>) {
      if (range.subject_length && !set_keys_.count(path)) {
        field *= factor_;
        scaled_.push_back(path);
      }
    }
  }

 private:
  double factor_;
  const SetKeys& set_keys_;
  std::string path_;
  std::vector<std::string>& scaled_;
};

class Writer {
 public:
  explicit Writer(YAML::Node& node) : node_(node) {}
  template <class T>
  void operator()(const char* key, T& field, const char* /*help*/, Range = {}) {
    node_[key] = to_node(field);
  }
  template <class T>
  static YAML::Node to_node(const T& value) {
    if constexpr (std::is_same_v<T, YAML::Node>) {
      return YAML::Clone(value);
    } else if constexpr (is_options<T>::value) {
      YAML::Node n(YAML::NodeType::Map);
      Writer w(n);
      const_cast<T&>(value).visit(w);
      return n;
    } else if constexpr (is_vector<T>::value) {
      YAML::Node n(YAML::NodeType::Sequence);
      for (const auto& v : value) n.push_back(to_node(v));
      return n;
    } else {
      return YAML::Node(value);
    }
  }

 private:
  YAML::Node& node_;
};

}  // namespace config_detail

// Maps `node` onto `opts`; `file` and `path` only name the source in error messages. With
// `set_keys`, the full path of every key the node sets is added to it.
template <class T>
void read_options(const std::string& file, const YAML::Node& node, const std::string& path,
                  T& opts, SetKeys* set_keys = nullptr) {
  if (!node.IsDefined() || node.IsNull()) {
    config_detail::call_check(opts, path);
    return;
  }
  config_detail::read_value(file, node, path, opts, Range{}, set_keys);
}

// Multiplies every subject-relative length of `opts` (declared with Length, in visit() or
// internal_lengths()) whose key path (`path` + "." + key, as read_options records it) is not in
// `set_keys` by `factor`, then runs the options' check() again. Returns the paths of the
// lengths it scaled.
template <class T>
std::vector<std::string> scale_unset_lengths(T& opts, double factor, const SetKeys& set_keys,
                                             const std::string& path) {
  std::vector<std::string> scaled;
  config_detail::Scaler(factor, set_keys, path, scaled).scale_struct(opts, path);
  config_detail::call_check(opts, path);
  return scaled;
}

template <class T>
YAML::Node to_yaml(const T& opts) {
  return config_detail::Writer::to_node(opts);
}

// Loads a YAML file; a syntax error becomes a ConfigError naming file and line.
YAML::Node load_yaml_file(const std::filesystem::path& path);

// One line per field: "key (default value): help", nested structs indented. For --help.
template <class T>
std::string describe_options(const T& opts, const std::string& indent = "  ");

namespace config_detail {
class Describer {
 public:
  Describer(std::string& out, std::string indent) : out_(out), indent_(std::move(indent)) {}
  template <class T>
  void operator()(const char* key, T& field, const char* help, Range range = {}) {
    if constexpr (std::is_same_v<T, YAML::Node>) {
      out_ += fmt::format("{}{}: {}\n", indent_, key, help);
    } else if constexpr (is_options<T>::value) {
      out_ += fmt::format("{}{}: {}\n", indent_, key, help);
      Describer d(out_, indent_ + "  ");
      field.visit(d);
    } else if constexpr (is_vector<T>::value) {
      if constexpr (is_options<typename T::value_type>::value) {
        out_ += fmt::format("{}{} (list): {}\n", indent_, key, help);
      } else {
        std::string items;
        for (const auto& item : field) items += (items.empty() ? "" : ", ") + scalar(item);
        out_ += fmt::format("{}{} = [{}]{}: {}\n", indent_, key, items, marker(range), help);
      }
    } else {
      out_ += fmt::format("{}{} = {}{}: {}\n", indent_, key, scalar(field), marker(range), help);
    }
  }

  // After the default of a subject-relative length: it is the reference subject's.
  static const char* marker(const Range& range) {
    return range.subject_length ? " (scaled to the subject)" : "";
  }

  // Shortest round-trip text: 0.1, not 0.10000000000000001.
  template <class T>
  static std::string scalar(const T& value) {
    if constexpr (std::is_same_v<T, bool>) {
      return value ? "true" : "false";
    } else if constexpr (std::is_same_v<T, std::string>) {
      return value.empty() ? "\"\"" : value;
    } else {
      return fmt::format("{}", value);
    }
  }

 private:
  std::string& out_;
  std::string indent_;
};
}  // namespace config_detail

template <class T>
std::string describe_options(const T& opts, const std::string& indent) {
  std::string out;
  config_detail::Describer d(out, indent);
  const_cast<T&>(opts).visit(d);
  return out;
}

}  // namespace fourd
