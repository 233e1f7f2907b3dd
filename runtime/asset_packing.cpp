#include "runtime/asset_packing.h"

#include <fmt/format.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <numbers>
#include <string>
#include <vector>

#include "pipeline/core/error.h"

namespace fourd {

namespace {

// Grid coordinates beyond this many steps are refused (their differences must fit 32 bits).
constexpr double kMaxSteps = 1 << 30;

std::uint32_t zigzag(std::int64_t d) {
  return static_cast<std::uint32_t>((static_cast<std::uint64_t>(d) << 1) ^
                                    static_cast<std::uint64_t>(d >> 63));
}
std::int64_t unzigzag(std::uint32_t z) {
  return static_cast<std::int64_t>(z >> 1) ^ -static_cast<std::int64_t>(z & 1);
}

// Integer grid values as [sequence][frame][channel][vertex]: the differences from the previous
// frame of the same sequence, zig-zag coded, as 4 byte planes (every value's low byte first).
struct GridValues {
  int sequences = 0, frames = 0, channels = 0, vertices = 0;
  std::vector<std::int64_t> q;
  std::size_t at(int s, int f, int c, int v) const {
    return ((static_cast<std::size_t>(s) * frames + f) * channels + c) * vertices + v;
  }
  void resize(int s, int f, int c, int v) {
    sequences = s, frames = f, channels = c, vertices = v;
    q.assign(static_cast<std::size_t>(s) * f * c * v, 0);
  }
};

void write_grid(BinaryWriter& w, const GridValues& g) {
  const std::size_t n = g.q.size();
  std::vector<std::uint8_t> planes(4 * n);
  for (int s = 0; s < g.sequences; ++s) {
    for (int f = 0; f < g.frames; ++f) {
      for (int c = 0; c < g.channels; ++c) {
        for (int v = 0; v < g.vertices; ++v) {
          const std::size_t i = g.at(s, f, c, v);
          const std::int64_t previous = f == 0 ? 0 : g.q[g.at(s, f - 1, c, v)];
          const std::uint32_t z = zigzag(g.q[i] - previous);
          for (int b = 0; b < 4; ++b) planes[b * n + i] = static_cast<std::uint8_t>(z >> (8 * b));
        }
      }
    }
  }
  w.write_vector(planes);
}

void read_grid(BinaryReader& r, const std::string& what, GridValues* g) {
  const std::vector<std::uint8_t> planes = r.read_vector<std::uint8_t>();
  const std::size_t n = g->q.size();
  if (planes.size() != 4 * n) {
    throw InputError(fmt::format("{}: {}: {} bytes of packed values, expected 4 x {}",
                                 r.path().string(), what, planes.size(), n));
  }
  for (int s = 0; s < g->sequences; ++s) {
    for (int f = 0; f < g->frames; ++f) {
      for (int c = 0; c < g->channels; ++c) {
        for (int v = 0; v < g->vertices; ++v) {
          const std::size_t i = g->at(s, f, c, v);
          std::uint32_t z = 0;
          for (int b = 0; b < 4; ++b) z |= static_cast<std::uint32_t>(planes[b * n + i]) << (8 * b);
          g->q[i] = (f == 0 ? 0 : g->q[g->at(s, f - 1, c, v)]) + unzigzag(z);
        }
      }
    }
  }
}

std::int64_t to_grid(double value, double step, const std::string& what) {
  const double q = std::round(value / step);
  if (!(std::abs(q) < kMaxSteps)) {
    throw InputError(fmt::format("{}: value {} is not finite or more than 2^30 steps of {} from "
                                 "the origin",
                                 what, value, step));
  }
  return static_cast<std::int64_t>(q);
}

double read_step(BinaryReader& r, const std::string& what) {
  const double step = r.read<double>();
  if (!(step > 0 && std::isfinite(step))) {
    throw InputError(fmt::format("{}: {}: grid step {}", r.path().string(), what, step));
  }
  return step;
}

// Octahedral coordinates of a direction in [-1, 1]^2 (a zero vector: the +z direction).
std::array<double, 2> octahedral(double x, double y, double z) {
  const double l1 = std::abs(x) + std::abs(y) + std::abs(z);
  if (l1 == 0) return {0, 0};
  double u = x / l1, v = y / l1;
  if (z < 0) {
    const double su = u >= 0 ? 1 : -1, sv = v >= 0 ? 1 : -1;
    const double uu = (1 - std::abs(v)) * su, vv = (1 - std::abs(u)) * sv;
    u = uu;
    v = vv;
  }
  return {u, v};
}

std::array<double, 3> from_octahedral(double u, double v) {
  double z = 1 - std::abs(u) - std::abs(v);
  if (z < 0) {
    const double su = u >= 0 ? 1 : -1, sv = v >= 0 ? 1 : -1;
    const double uu = (1 - std::abs(v)) * su, vv = (1 - std::abs(u)) * sv;
    u = uu;
    v = vv;
  }
  const double norm = std::sqrt(u * u + v * v + z * z);
  return {u / norm, v / norm, z / norm};
}

// Position-like frames (planes x | y | z, `count` frames): grid values and back.
void frames_to_grid(const AlignedFloats& frames, const BlendSpace& b, int count,
                    const std::array<double, 3>& origin, double step, const std::string& what,
                    GridValues* g) {
  g->resize(count, b.num_frames, 3, b.num_vertices);
  const std::size_t stride = b.plane_stride;
  for (int s = 0; s < count; ++s) {
    for (int f = 0; f < b.num_frames; ++f) {
      const float* frame = frames.data() + (static_cast<std::size_t>(s) * b.num_frames + f) * 3 * stride;
      for (int c = 0; c < 3; ++c) {
        for (int v = 0; v < b.num_vertices; ++v) {
          g->q[g->at(s, f, c, v)] = to_grid(frame[c * stride + v] - origin[c], step, what);
        }
      }
    }
  }
}

void halves_to_grid(const AlignedHalfs& halves, const BlendSpace& b, int count, double step,
                    const std::string& what, GridValues* g) {
  g->resize(count, b.num_frames, 3, b.num_vertices);
  const std::size_t stride = b.plane_stride;
  for (int s = 0; s < count; ++s) {
    for (int f = 0; f < b.num_frames; ++f) {
      const std::uint16_t* frame =
          halves.data() + (static_cast<std::size_t>(s) * b.num_frames + f) * 3 * stride;
      for (int c = 0; c < 3; ++c) {
        for (int v = 0; v < b.num_vertices; ++v) {
          g->q[g->at(s, f, c, v)] = to_grid(half_to_float(frame[c * stride + v]), step, what);
        }
      }
    }
  }
}

void grid_to_halves(const GridValues& g, const BlendSpace& b, double step, AlignedHalfs* halves) {
  const std::size_t stride = b.plane_stride;
  halves->assign(static_cast<std::size_t>(g.sequences) * b.num_frames * 3 * stride, 0);
  for (int s = 0; s < g.sequences; ++s) {
    for (int f = 0; f < b.num_frames; ++f) {
      std::uint16_t* frame =
          halves->data() + (static_cast<std::size_t>(s) * b.num_frames + f) * 3 * stride;
      for (int c = 0; c < 3; ++c) {
        for (int v = 0; v < b.num_vertices; ++v) {
          frame[c * stride + v] =
              float_to_half(static_cast<float>(static_cast<double>(g.q[g.at(s, f, c, v)]) * step));
        }
      }
    }
  }
}

}  // namespace

void AssetPacking::check() const {
  for (const auto& [name, step] : {std::pair<const char*, double>{"position step", position_step},
                                   {"displacement step", displacement_step},
                                   {"normal displacement step", normal_displacement_step}}) {
    if (!(step > 0 && std::isfinite(step))) {
      throw ConfigError(fmt::format("web package: {} must be positive, not {}", name, step));
    }
  }
  if (normal_bits < 8 || normal_bits > 16) {
    throw ConfigError(fmt::format("web package: normal bits must be 8 to 16, not {}", normal_bits));
  }
}

void write_packed_geometry(BinaryWriter& w, const GraphSpace& space, const AssetPacking& p) {
  const BlendSpace& b = space.motion.blend;
  const int n = b.num_inputs, refs = b.num_references() - b.num_inputs;
  const std::string what = fmt::format("web package of motion space '{}'", space.name());
  const std::size_t stride = b.plane_stride;
  // Positions: the grid's origin is the bounding box's minimum over every input frame.
  std::array<double, 3> origin{0, 0, 0};
  for (int c = 0; c < 3; ++c) {
    double lo = std::numeric_limits<double>::infinity();
    for (int s = 0; s < n; ++s) {
      for (int f = 0; f < b.num_frames; ++f) {
        const float* plane = b.frame(s, f) + c * stride;
        for (int v = 0; v < b.num_vertices; ++v) lo = std::min(lo, static_cast<double>(plane[v]));
      }
    }
    origin[c] = std::isfinite(lo) ? lo : 0.0;
  }
  GridValues g;
  frames_to_grid(b.frames, b, n, origin, p.position_step, what + ", positions", &g);
  w.write<double>(p.position_step);
  for (double o : origin) w.write<double>(o);
  write_grid(w, g);
  // Normals: octahedral coordinates.
  const double scale = (1 << (p.normal_bits - 1)) - 1;
  g.resize(n, b.num_frames, 2, b.num_vertices);
  for (int s = 0; s < n; ++s) {
    for (int f = 0; f < b.num_frames; ++f) {
      const float* frame = space.normals.data() + (static_cast<std::size_t>(s) * b.num_frames + f) * 3 * stride;
      for (int v = 0; v < b.num_vertices; ++v) {
        const double x = frame[v], y = frame[stride + v], z = frame[2 * stride + v];
        if (!std::isfinite(x) || !std::isfinite(y) || !std::isfinite(z)) {
          throw InputError(fmt::format("{}: normal of vertex {} at frame {} of input {} is not "
                                       "finite",
                                       what, v, f, s));
        }
        const std::array<double, 2> uv = octahedral(x, y, z);
        g.q[g.at(s, f, 0, v)] = std::lround(uv[0] * scale);
        g.q[g.at(s, f, 1, v)] = std::lround(uv[1] * scale);
      }
    }
  }
  w.write<std::int32_t>(p.normal_bits);
  write_grid(w, g);
  // Displacements of the other references.
  halves_to_grid(b.displacements, b, refs, p.displacement_step, what + ", displacements", &g);
  w.write<double>(p.displacement_step);
  write_grid(w, g);
  halves_to_grid(space.normal_displacements, b, refs, p.normal_displacement_step,
                 what + ", normal displacements", &g);
  w.write<double>(p.normal_displacement_step);
  write_grid(w, g);
}

void read_packed_geometry(BinaryReader& r, GraphSpace* space) {
  BlendSpace& b = space->motion.blend;
  const std::string what = fmt::format("web package of motion space '{}'", space->name());
  if (b.num_inputs < 1 || b.num_inputs > 3 || b.num_vertices < 1 || b.num_frames < 1 ||
      b.plane_stride != blend_plane_stride(b.num_vertices) ||
      b.reference_weights.size() % b.num_inputs != 0 || b.num_references() < b.num_inputs ||
      static_cast<std::size_t>(b.num_references()) * b.num_frames * b.num_vertices > (1u << 28)) {
    throw InputError(fmt::format("{}: {}: bad sizes ({} inputs, {} vertices, {} frames, {} "
                                 "reference weights)",
                                 r.path().string(), what, b.num_inputs, b.num_vertices,
                                 b.num_frames, b.reference_weights.size()));
  }
  const int n = b.num_inputs, refs = b.num_references() - b.num_inputs;
  const std::size_t stride = b.plane_stride;
  GridValues g;
  // Positions.
  const double step = read_step(r, what + ", positions");
  std::array<double, 3> origin{};
  for (double& o : origin) o = r.read<double>();
  g.resize(n, b.num_frames, 3, b.num_vertices);
  read_grid(r, what + ", positions", &g);
  b.frames.assign(static_cast<std::size_t>(n) * b.num_frames * b.frame_stride(), 0.f);
  for (int s = 0; s < n; ++s) {
    for (int f = 0; f < b.num_frames; ++f) {
      float* frame = b.frame(s, f);
      for (int c = 0; c < 3; ++c) {
        for (int v = 0; v < b.num_vertices; ++v) {
          frame[c * stride + v] =
              static_cast<float>(origin[c] + static_cast<double>(g.q[g.at(s, f, c, v)]) * step);
        }
      }
    }
  }
  // Normals.
  const int bits = r.read<std::int32_t>();
  if (bits < 8 || bits > 16) {
    throw InputError(fmt::format("{}: {}: {} bits per normal coordinate (8 to 16)",
                                 r.path().string(), what, bits));
  }
  const double scale = (1 << (bits - 1)) - 1;
  g.resize(n, b.num_frames, 2, b.num_vertices);
  read_grid(r, what + ", normals", &g);
  space->normals.assign(b.frames.size(), 0.f);
  for (int s = 0; s < n; ++s) {
    for (int f = 0; f < b.num_frames; ++f) {
      float* frame = space->normals.data() + (static_cast<std::size_t>(s) * b.num_frames + f) * 3 * stride;
      for (int v = 0; v < b.num_vertices; ++v) {
        const double u = static_cast<double>(g.q[g.at(s, f, 0, v)]) / scale;
        const double w = static_cast<double>(g.q[g.at(s, f, 1, v)]) / scale;
        if (!(std::abs(u) <= 1 && std::abs(w) <= 1)) {
          throw InputError(fmt::format("{}: {}: normal of vertex {} at frame {} of input {} is "
                                       "off the octahedron",
                                       r.path().string(), what, v, f, s));
        }
        const std::array<double, 3> d = from_octahedral(u, w);
        for (int c = 0; c < 3; ++c) frame[c * stride + v] = static_cast<float>(d[c]);
      }
    }
  }
  // Displacements.
  const double dstep = read_step(r, what + ", displacements");
  g.resize(refs, b.num_frames, 3, b.num_vertices);
  read_grid(r, what + ", displacements", &g);
  grid_to_halves(g, b, dstep, &b.displacements);
  const double nstep = read_step(r, what + ", normal displacements");
  read_grid(r, what + ", normal displacements", &g);
  grid_to_halves(g, b, nstep, &space->normal_displacements);
}

}  // namespace fourd

namespace fourd {

PackingError packing_error(const MotionGraph& original, const MotionGraph& decoded) {
  if (original.spaces.size() != decoded.spaces.size()) {
    throw InputError(fmt::format("packing error: {} spaces against {}", original.spaces.size(),
                                 decoded.spaces.size()));
  }
  PackingError e;
  for (std::size_t k = 0; k < original.spaces.size(); ++k) {
    const GraphSpace& a = original.spaces[k];
    const GraphSpace& b = decoded.spaces[k];
    const BlendSpace& ba = a.motion.blend;
    const BlendSpace& bb = b.motion.blend;
    if (ba.num_inputs != bb.num_inputs || ba.num_references() != bb.num_references() ||
        ba.num_vertices != bb.num_vertices || ba.num_frames != bb.num_frames ||
        ba.plane_stride != bb.plane_stride || a.normals.size() != b.normals.size() ||
        a.normal_displacements.size() != b.normal_displacements.size()) {
      throw InputError(fmt::format("packing error: motion space '{}' differs in sizes", a.name()));
    }
    const std::size_t stride = ba.plane_stride;
    std::vector<float> ma(ba.frame_stride()), mb(ba.frame_stride());
    for (int r = 0; r < ba.num_references(); ++r) {
      for (int f = 0; f < ba.num_frames; ++f) {
        reference_frame(ba, r, f, ma.data());
        reference_frame(bb, r, f, mb.data());
        for (int v = 0; v < ba.num_vertices; ++v) {
          double d2 = 0;
          for (int c = 0; c < 3; ++c) {
            const double d = static_cast<double>(ma[c * stride + v]) - mb[c * stride + v];
            d2 += d * d;
          }
          e.position_m = std::max(e.position_m, std::sqrt(d2));
        }
      }
    }
    for (std::size_t frame = 0; frame < a.normals.size(); frame += 3 * stride) {
      for (std::size_t v = 0; v < static_cast<std::size_t>(ba.num_vertices); ++v) {
        double dot = 0, la = 0, lb = 0;
        for (std::size_t c = 0; c < 3; ++c) {
          const double x = a.normals[frame + c * stride + v], y = b.normals[frame + c * stride + v];
          dot += x * y;
          la += x * x;
          lb += y * y;
        }
        if (la == 0 || lb == 0) continue;  // no direction to compare
        const double cosine = std::clamp(dot / std::sqrt(la * lb), -1.0, 1.0);
        e.normal_deg = std::max(e.normal_deg, std::acos(cosine) * 180 / std::numbers::pi);
      }
    }
    for (std::size_t i = 0; i < a.normal_displacements.size(); ++i) {
      e.normal_displacement =
          std::max(e.normal_displacement, std::abs(static_cast<double>(half_to_float(a.normal_displacements[i])) -
                                                   half_to_float(b.normal_displacements[i])));
    }
  }
  return e;
}

}  // namespace fourd
