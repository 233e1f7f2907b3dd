#include "pipeline/exchange/warped_class.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <numbers>

#include "pipeline/core/binary_format.h"
#include "pipeline/core/error.h"

namespace fourd {

double TakeTiming::frame_at(double u) const {
  if (cyclic) return start + (u - std::floor(u)) * length;
  return std::clamp(u, 0.0, 1.0) * length;
}

double Warp::at(double u) const {
  const int m = static_cast<int>(knots.size()) - 1;
  const double pos = std::clamp(u, 0.0, 1.0) * m;
  const int i = std::min(static_cast<int>(std::floor(pos)), m - 1);
  const double a = pos - i;
  return offset + (1 - a) * knots[i] + a * knots[i + 1];
}

double Warp::inverse(double v) const {
  const int m = static_cast<int>(knots.size()) - 1;
  const double w = std::clamp(v - offset, 0.0, 1.0);
  const auto it = std::upper_bound(knots.begin(), knots.end(), w);
  const int b = std::clamp(static_cast<int>(it - knots.begin()), 1, m), a = b - 1;
  const double span = knots[b] - knots[a];
  const double f = span > 0 ? (w - knots[a]) / span : 0.0;
  return (a + std::clamp(f, 0.0, 1.0)) / m;
}

namespace {

constexpr FileMagic kTimewarpMagic("FOURDTW");
constexpr std::uint32_t kTimewarpVersion = 1;

void check_sizes(const std::filesystem::path& path, const WarpedClass& c) {
  const std::size_t f = c.num_samples, nv = c.num_vertices;
  auto fail = [&](const std::string& what) {
    throw InputError(fmt::format("{}: class {}: {}", path.string(), c.name, what));
  };
  if (c.num_samples < 2 || c.num_vertices < 1) fail("no samples or no vertices");
  if (c.template_positions.cols() != c.num_vertices) fail("template size differs");
  for (const Tri& t : c.triangles) {
    if (t.minCoeff() < 0 || t.maxCoeff() >= c.num_vertices) fail("triangle index out of range");
  }
  for (const WarpedTake& t : c.takes) {
    if (t.sample_frames.size() != f || t.seconds.size() != f || t.roots.size() != f ||
        t.shapes.size() != f * nv || static_cast<int>(t.frame_t.size()) != t.num_frames) {
      fail(fmt::format("take {} has inconsistent sizes", t.name));
    }
  }
}

}  // namespace

Eigen::Matrix3Xd WarpedClass::shape(int take, int sample) const {
  const Vec3f* p = takes[take].shapes.data() + static_cast<std::size_t>(sample) * num_vertices;
  Eigen::Matrix3Xd x(3, num_vertices);
  for (int v = 0; v < num_vertices; ++v) x.col(v) = p[v].cast<double>();
  return x;
}

void write_warped_class(const std::filesystem::path& path, const WarpedClass& c) {
  check_sizes(path, c);
  BinaryWriter w;
  w.write_string(c.name);
  w.write_string(c.parameter);
  w.write<std::uint8_t>(c.cyclic ? 1 : 0);
  w.write<double>(c.fps);
  w.write<std::int32_t>(c.num_vertices);
  w.write<std::int32_t>(c.num_samples);
  w.write_vector(c.triangles);
  w.write_matrix(Eigen::MatrixXd(c.template_positions));
  w.write<double>(c.character_height);
  w.write<std::uint64_t>(c.takes.size());
  for (const WarpedTake& t : c.takes) {
    w.write_string(t.name);
    w.write<std::int32_t>(t.num_frames);
    w.write<Cycle>(t.cycle);
    w.write<std::uint8_t>(t.timing.cyclic ? 1 : 0);  // field by field: no padding bytes
    w.write<double>(t.timing.start);
    w.write<double>(t.timing.length);
    w.write<double>(t.warp.offset);
    w.write_vector(t.warp.knots);
    w.write_vector(t.frame_t);
    w.write_vector(t.sample_frames);
    w.write_vector(t.seconds);
    w.write_vector(t.roots);
    w.write_vector(t.shapes);
  }
  w.save(path, kTimewarpMagic, kTimewarpVersion);
}

WarpedClass read_warped_class(const std::filesystem::path& path) {
  BinaryReader r = BinaryReader::open(path, kTimewarpMagic, {kTimewarpVersion});
  WarpedClass c;
  c.name = r.read_string();
  c.parameter = r.read_string();
  c.cyclic = r.read<std::uint8_t>() != 0;
  c.fps = r.read<double>();
  c.num_vertices = r.read<std::int32_t>();
  c.num_samples = r.read<std::int32_t>();
  c.triangles = r.read_vector<Tri>();
  // Checked before the assignment: a 3 x N matrix cannot hold another row count.
  const Eigen::MatrixXd positions = r.read_matrix<Eigen::MatrixXd>();
  if (positions.rows() != 3) {
    throw InputError(fmt::format("{}: the template is not 3 x #V", path.string()));
  }
  c.template_positions = positions;
  c.character_height = r.read<double>();
  const auto num_takes = r.read<std::uint64_t>();
  if (num_takes > 3) {
    throw InputError(fmt::format("{}: {} takes in one class (at most 3)", path.string(), num_takes));
  }
  for (std::uint64_t k = 0; k < num_takes; ++k) {
    WarpedTake t;
    t.name = r.read_string();
    t.num_frames = r.read<std::int32_t>();
    t.cycle = r.read<Cycle>();
    t.timing.cyclic = r.read<std::uint8_t>() != 0;
    t.timing.start = r.read<double>();
    t.timing.length = r.read<double>();
    t.warp.offset = r.read<double>();
    t.warp.knots = r.read_vector<double>();
    t.frame_t = r.read_vector<double>();
    t.sample_frames = r.read_vector<double>();
    t.seconds = r.read_vector<double>();
    t.roots = r.read_vector<RootTransform>();
    t.shapes = r.read_vector<Vec3f>();
    c.takes.push_back(std::move(t));
  }
  r.expect_end();
  check_sizes(path, c);
  return c;
}

nlohmann::json warped_class_summary(const WarpedClass& c) {
  using nlohmann::json;
  json takes = json::array();
  for (const WarpedTake& t : c.takes) {
    const RootTransform& end = t.roots.back();
    const double duration = t.seconds.back();
    json take = {{"take", t.name},
                 {"frames", t.num_frames},
                 {"duration_s", duration},
                 {"phase_offset", t.warp.offset},
                 {"frame_t", t.frame_t},
                 {"sample_frames", t.sample_frames},
                 {"root_displacement_m", {end.x, end.y}},
                 {"root_turn_deg", end.heading * 180 / std::numbers::pi},
                 {"root_speed_m_per_s", std::hypot(end.x, end.y) / duration}};
    if (c.cyclic) {
      take["cycle_start_frame"] = t.cycle.start;
      take["cycle_frames"] = t.cycle.period;
      take["closure_rms_m"] = t.cycle.closure_rms;
      take["variation_rms_m"] = t.cycle.variation_rms;
      take["closure_ratio"] = t.cycle.closure_ratio;
    }
    takes.push_back(std::move(take));
  }
  return {{"class", c.name},
          {"parameter", c.parameter},
          {"cyclic", c.cyclic},
          {"fps", c.fps},
          {"samples", c.num_samples},
          {"vertices", c.num_vertices},
          {"character_height_m", c.character_height},
          {"reference_take", c.takes.empty() ? "" : c.takes.front().name},
          {"takes", takes}};
}

}  // namespace fourd
