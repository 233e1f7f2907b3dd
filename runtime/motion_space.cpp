#include "runtime/motion_space.h"

#include <fmt/format.h>

#include <algorithm>
#include <cassert>
#include <cmath>
#include <cstdint>

#include "pipeline/core/binary_format.h"
#include "pipeline/core/error.h"

namespace fourd {

namespace {

constexpr FileMagic kMotionSpaceMagic("FOURDMS");
// Version 2: a reference at the midpoint of a cell edge is that cell's quadratic midpoint node
// (runtime/blend.h), and the cells' arc angles follow the cells. A version 1 file (no arc
// angles; its cells have no midpoint references, so every cell is linear) still loads and
// blends exactly as it did.
// Version 3: the inputs' frames in float, the other references as fp16 displacements from the
// linear blend (runtime/blend.h). Versions 1 and 2 store every reference's frames in float;
// they load converted to displacements.
constexpr std::uint32_t kMotionSpaceVersion = 3;
constexpr std::uint32_t kMotionSpaceVersionLinearCells = 1;
constexpr std::uint32_t kMotionSpaceVersionFloatReferences = 2;

// Weights projected onto the simplex exactly as runtime/blend.h does.
std::array<double, 3> simplex_weights(std::span<const float> w, int n) {
  assert(static_cast<int>(w.size()) >= n);
  std::array<double, 3> p{};
  double sum = 0;
  for (int i = 0; i < n; ++i) sum += (p[i] = std::max(0.0, static_cast<double>(w[i])));
  for (int i = 0; i < n; ++i) p[i] = sum > 0 ? p[i] / sum : 1.0 / n;
  return p;
}

// Sample interval [i, i + 1] holding t and the fraction a along it (i = F - 2, a = 1 at t = 1).
void sample_interval(int num_samples, double t, int* i, double* a) {
  if (num_samples < 2) {
    *i = 0;
    *a = 0;
    return;
  }
  const double pos = std::clamp(t, 0.0, 1.0) * (num_samples - 1);
  *i = std::min(static_cast<int>(std::floor(pos)), num_samples - 2);
  *a = pos - *i;
}

}  // namespace

template <class T>
std::vector<T, AlignedAllocator<T>> read_aligned(BinaryReader& r, const char* what) {
  const auto count = r.read<std::uint64_t>();
  if (count > r.remaining() / sizeof(T)) {
    throw InputError(fmt::format("{}: truncated {} ({} values announced, {} bytes left)",
                                 r.path().string(), what, count, r.remaining()));
  }
  std::vector<T, AlignedAllocator<T>> values(count);
  r.read_bytes(values.data(), count * sizeof(T));
  return values;
}
template AlignedFloats read_aligned<float>(BinaryReader&, const char*);
template AlignedHalfs read_aligned<std::uint16_t>(BinaryReader&, const char*);

void MotionSpace::check() const {
  blend.check();
  const int n = blend.num_inputs, f = blend.num_frames;
  if (static_cast<int>(takes.size()) != n) {
    throw InputError(fmt::format("motion space '{}': {} take names for {} inputs", name,
                                 takes.size(), n));
  }
  if (roots.size() != static_cast<std::size_t>(n) * f ||
      seconds.size() != static_cast<std::size_t>(n) * f) {
    throw InputError(fmt::format("motion space '{}': {} root poses and {} times for {} inputs x {} "
                                 "samples",
                                 name, roots.size(), seconds.size(), n, f));
  }
  for (int k = 0; k < n; ++k) {
    for (int i = 0; i < f; ++i) {
      const RootPose& r = root(k, i);
      if (!std::isfinite(r.x) || !std::isfinite(r.y) || !std::isfinite(r.heading) ||
          !std::isfinite(time(k, i))) {
        throw InputError(fmt::format("motion space '{}': take {} sample {} is not finite", name,
                                     takes[k], i));
      }
      if (i > 0 && !(time(k, i) > time(k, i - 1))) {
        throw InputError(fmt::format("motion space '{}': take {}: time does not increase at sample "
                                     "{}",
                                     name, takes[k], i));
      }
    }
  }
  for (const Tri& t : triangles) {
    if (t.minCoeff() < 0 || t.maxCoeff() >= blend.num_vertices) {
      throw InputError(fmt::format("motion space '{}': triangle ({}, {}, {}) indexes past {} "
                                   "vertices",
                                   name, t[0], t[1], t[2], blend.num_vertices));
    }
  }
  if (!(character_height > 0)) {
    throw InputError(fmt::format("motion space '{}': character height {} is not positive", name,
                                 character_height));
  }
  if (parameter_map.num_inputs != n) {
    throw InputError(fmt::format("motion space '{}': parameter map for {} inputs, space has {}",
                                 name, parameter_map.num_inputs, n));
  }
  parameter_map.check();
}

MotionSample make_motion_sample(const MotionSpace& space) {
  MotionSample s;
  s.shape = make_blended_frame(space.blend);
  return s;
}

RootPose blended_root(const MotionSpace& space, double t, std::span<const float> w) {
  const int n = space.num_inputs();
  const std::array<double, 3> p = simplex_weights(w, n);
  int i = 0;
  double a = 0;
  sample_interval(space.num_samples(), t, &i, &a);
  const int j = std::min(i + 1, space.num_samples() - 1);
  double x = 0, y = 0, h = 0;
  for (int k = 0; k < n; ++k) {
    const RootPose& r0 = space.root(k, i);
    const RootPose& r1 = space.root(k, j);
    x += p[k] * ((1 - a) * r0.x + a * r1.x);
    y += p[k] * ((1 - a) * r0.y + a * r1.y);
    h += p[k] * ((1 - a) * r0.heading + a * r1.heading);
  }
  return {static_cast<float>(x), static_cast<float>(y), static_cast<float>(h)};
}

double blended_seconds_per_t(const MotionSpace& space, double t, std::span<const float> w) {
  const int n = space.num_inputs(), f = space.num_samples();
  if (f < 2) return 0;
  const std::array<double, 3> p = simplex_weights(w, n);
  int i = 0;
  double a = 0;
  sample_interval(f, t, &i, &a);
  double rate = 0;
  for (int k = 0; k < n; ++k) rate += p[k] * (space.time(k, i + 1) - space.time(k, i));
  return rate * (f - 1);
}

double blended_duration(const MotionSpace& space, std::span<const float> w) {
  const int n = space.num_inputs(), f = space.num_samples();
  const std::array<double, 3> p = simplex_weights(w, n);
  double d = 0;
  for (int k = 0; k < n; ++k) d += p[k] * (space.time(k, f - 1) - space.time(k, 0));
  return d;
}

void evaluate_motion_space_weights(const MotionSpace& space, double t, std::span<const float> w,
                                   MotionSample* out) {
  const int n = space.num_inputs();
  const std::array<double, 3> p = simplex_weights(w, n);
  for (int k = 0; k < 3; ++k) out->weights[k] = k < n ? static_cast<float>(p[k]) : 0.f;
  const std::span<const float> pw(out->weights.data(), n);
  blend_hybrid(space.blend, t, pw, &out->shape);
  out->root = blended_root(space, t, pw);
  out->seconds_per_t = blended_seconds_per_t(space, t, pw);
  out->duration = blended_duration(space, pw);
}

void evaluate_motion_space(const MotionSpace& space, double t, double p, MotionSample* out) {
  std::array<float, 3> w{};
  out->parameter = weights_for_parameter(space.parameter_map, p,
                                         std::span<float>(w.data(), space.num_inputs()));
  evaluate_motion_space_weights(space, t, std::span<const float>(w.data(), space.num_inputs()),
                                out);
}

void write_motion_space_fields(BinaryWriter& w, const MotionSpace& space) {
  const BlendSpace& b = space.blend;
  w.write_string(space.name);
  w.write<std::uint8_t>(space.cyclic ? 1 : 0);
  w.write<std::uint64_t>(space.takes.size());
  for (const std::string& take : space.takes) w.write_string(take);
  w.write<double>(space.character_height);
  w.write_vector(space.triangles);
  w.write<std::int32_t>(b.num_inputs);
  w.write<std::int32_t>(b.num_vertices);
  w.write<std::int32_t>(b.num_frames);
  w.write<std::int32_t>(b.plane_stride);
  w.write_vector(b.reference_weights);
  w.write_span(std::span<const float>(b.frames.data(), b.frames.size()));
  w.write_span(std::span<const std::uint16_t>(b.displacements.data(), b.displacements.size()));
  w.write_vector(b.cells);
  w.write_vector(b.cell_arc_angles);
  w.write_vector(space.roots);
  w.write_vector(space.seconds);
  const ParameterMap& m = space.parameter_map;
  w.write_string(m.parameter);
  w.write_string(m.unit);
  w.write<std::int32_t>(m.num_inputs);
  w.write_vector(m.path);
  w.write_vector(m.values);
}

MotionSpace read_motion_space_fields(BinaryReader& r, MotionSpaceLayout layout) {
  MotionSpace s;
  s.name = r.read_string();
  s.cyclic = r.read<std::uint8_t>() != 0;
  const auto num_takes = r.read<std::uint64_t>();
  if (num_takes > 3) {
    throw InputError(fmt::format("{}: motion space '{}' has {} takes (1 to 3 supported)",
                                 r.path().string(), s.name, num_takes));
  }
  for (std::uint64_t k = 0; k < num_takes; ++k) s.takes.push_back(r.read_string());
  s.character_height = r.read<double>();
  s.triangles = r.read_vector<Tri>();
  BlendSpace& b = s.blend;
  b.num_inputs = r.read<std::int32_t>();
  b.num_vertices = r.read<std::int32_t>();
  b.num_frames = r.read<std::int32_t>();
  b.plane_stride = r.read<std::int32_t>();
  b.reference_weights = r.read_vector<double>();
  if (layout.displacements) {
    b.frames = read_aligned<float>(r, "blend frames");
    b.displacements = read_aligned<std::uint16_t>(r, "blend displacements");
  } else {
    const AlignedFloats all = read_aligned<float>(r, "blend frames");
    try {
      split_reference_frames(b, all, &b.frames, &b.displacements);
    } catch (const InputError& e) {
      throw InputError(
          fmt::format("{}: motion space '{}': {}", r.path().string(), s.name, e.what()));
    }
  }
  b.cells = r.read_vector<std::array<int, 3>>();
  if (layout.arc_angles) b.cell_arc_angles = r.read_vector<double>();
  s.roots = r.read_vector<RootPose>();
  s.seconds = r.read_vector<float>();
  ParameterMap& m = s.parameter_map;
  m.parameter = r.read_string();
  m.unit = r.read_string();
  m.num_inputs = r.read<std::int32_t>();
  m.path = r.read_vector<double>();
  m.values = r.read_vector<double>();
  return s;
}

void save_motion_space(const std::filesystem::path& path, const MotionSpace& space) {
  space.check();
  BinaryWriter w;
  w.reserve(space.blend.frames.size() * sizeof(float) +
            space.blend.displacements.size() * sizeof(std::uint16_t) + 4096);
  write_motion_space_fields(w, space);
  w.save(path, kMotionSpaceMagic, kMotionSpaceVersion);
}

MotionSpace load_motion_space(const std::filesystem::path& path) {
  BinaryReader r = BinaryReader::open(
      path, kMotionSpaceMagic,
      {kMotionSpaceVersionLinearCells, kMotionSpaceVersionFloatReferences, kMotionSpaceVersion});
  MotionSpace s =
      read_motion_space_fields(r, {.arc_angles = r.version() >= kMotionSpaceVersionFloatReferences,
                                   .displacements = r.version() >= kMotionSpaceVersion});
  r.expect_end();
  try {
    s.check();
  } catch (const InputError& e) {
    throw InputError(fmt::format("{}: {}", path.string(), e.what()));
  }
  return s;
}

}  // namespace fourd
