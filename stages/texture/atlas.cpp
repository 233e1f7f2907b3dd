#include "stages/texture/atlas.h"

#include <fmt/format.h>

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <deque>
#include <limits>
#include <numbers>
#include <queue>
#include <unordered_map>

#include "pipeline/core/error.h"
#include "pipeline/geometry/parameterize.h"

namespace fourd::texture {
namespace {

using Eigen::Vector2d;
using Eigen::Vector3d;

// "lscm" / "arap"; ConfigError naming `field` for anything else.
FlattenMethod parse_flatten_method(const std::string& name, const std::string& field) {
  if (name == "lscm") return FlattenMethod::kLscm;
  if (name == "arap") return FlattenMethod::kArap;
  throw ConfigError(fmt::format("{} = '{}': expected 'lscm' or 'arap'", field, name));
}

struct FaceGeometry {
  std::vector<Vector3d> normal;    // unit (zero for degenerate faces)
  std::vector<double> area;        // [m^2]
  std::vector<Vector3d> centroid;
};

FaceGeometry face_geometry(const Mesh& mesh) {
  FaceGeometry g;
  const std::size_t nf = mesh.triangles.size();
  g.normal.resize(nf);
  g.area.resize(nf);
  g.centroid.resize(nf);
  for (std::size_t f = 0; f < nf; ++f) {
    const Tri& t = mesh.triangles[f];
    const Vector3d p0 = mesh.positions[t[0]].cast<double>(), p1 = mesh.positions[t[1]].cast<double>(),
                   p2 = mesh.positions[t[2]].cast<double>();
    const Vector3d n = (p1 - p0).cross(p2 - p0);
    const double len = n.norm();
    g.area[f] = 0.5 * len;
    g.normal[f] = len > 0 ? Vector3d(n / len) : Vector3d::Zero();
    g.centroid[f] = (p0 + p1 + p2) / 3.0;
  }
  return g;
}

// Charts grown from seeds while face normals stay within `max_angle` of the chart's mean.
std::vector<std::vector<int>> grow_charts(const FaceGeometry& g,
                                          const std::vector<std::array<int, 3>>& neighbours,
                                          double max_angle_deg) {
  const int nf = static_cast<int>(g.area.size());
  const double min_cos = std::cos(max_angle_deg * std::numbers::pi / 180.0);
  std::vector<int> chart_of(nf, -1);
  std::vector<std::vector<int>> charts;
  using Entry = std::pair<double, int>;  // (1 - cos to the chart normal, face)
  for (int seed = 0; seed < nf; ++seed) {
    if (chart_of[seed] >= 0) continue;
    const int c = static_cast<int>(charts.size());
    charts.emplace_back();
    Vector3d normal_sum = Vector3d::Zero();
    std::priority_queue<Entry, std::vector<Entry>, std::greater<>> queue;
    queue.push({0.0, seed});
    while (!queue.empty()) {
      const int f = queue.top().second;
      queue.pop();
      if (chart_of[f] >= 0) continue;
      const Vector3d mean = normal_sum.squaredNorm() > 0 ? normal_sum.normalized() : g.normal[f];
      if (f != seed && g.normal[f].dot(mean) < min_cos) continue;
      chart_of[f] = c;
      charts[c].push_back(f);
      normal_sum += g.area[f] * g.normal[f];
      const Vector3d now = normal_sum.squaredNorm() > 0 ? normal_sum.normalized() : g.normal[f];
      for (int nb : neighbours[f]) {
        if (nb >= 0 && chart_of[nb] < 0) queue.push({1.0 - g.normal[nb].dot(now), nb});
      }
    }
  }
  return charts;
}

// Connected pieces of `faces` (through edges shared inside the set).
std::vector<std::vector<int>> connected_pieces(const std::vector<int>& faces,
                                               const std::vector<std::array<int, 3>>& neighbours,
                                               std::vector<int>& mark /* #F scratch, -1 */) {
  for (int f : faces) mark[f] = -2;  // in the set, not visited
  std::vector<std::vector<int>> pieces;
  for (int start : faces) {
    if (mark[start] != -2) continue;
    const int id = static_cast<int>(pieces.size());
    pieces.emplace_back();
    std::deque<int> queue{start};
    mark[start] = id;
    while (!queue.empty()) {
      const int f = queue.front();
      queue.pop_front();
      pieces[id].push_back(f);
      for (int nb : neighbours[f]) {
        if (nb >= 0 && mark[nb] == -2) {
          mark[nb] = id;
          queue.push_back(nb);
        }
      }
    }
  }
  for (int f : faces) mark[f] = -1;
  return pieces;
}

// Two halves of `faces` across the plane through their median, normal to their longest extent.
std::pair<std::vector<int>, std::vector<int>> split_faces(const std::vector<int>& faces,
                                                          const FaceGeometry& g) {
  Vector3d mean = Vector3d::Zero();
  for (int f : faces) mean += g.centroid[f];
  mean /= static_cast<double>(faces.size());
  Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();
  for (int f : faces) {
    const Vector3d d = g.centroid[f] - mean;
    cov += d * d.transpose();
  }
  const Vector3d axis = Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d>(cov).eigenvectors().col(2);
  std::vector<std::pair<double, int>> order;
  order.reserve(faces.size());
  for (int f : faces) order.push_back({g.centroid[f].dot(axis), f});
  std::sort(order.begin(), order.end());
  std::pair<std::vector<int>, std::vector<int>> halves;
  for (std::size_t i = 0; i < order.size(); ++i) {
    (i < order.size() / 2 ? halves.first : halves.second).push_back(order[i].second);
  }
  return halves;
}

// A flattened chart in its own frame: principal axis along x, box corner at the origin,
// plane area equal to surface area.
struct FlatChart {
  std::vector<int> faces;
  std::vector<int> vertices;            // mesh vertex of each local vertex
  std::vector<Tri> local_triangles;     // per face, local vertex indices
  std::vector<Vector2d> uv;             // per local vertex [m]
  Vector2d size = Vector2d::Zero();     // box [m]
  double area = 0;
  double stretch = 1;
};

// Flattens one chart; false when it must be split (not a disc, folds, too much stretch).
bool flatten(const Mesh& mesh, const std::vector<int>& faces, const AtlasOptions& options,
             FlattenMethod method, std::vector<int>& local_of /* #V scratch, -1 */,
             FlatChart* out) {
  FlatChart chart;
  chart.faces = faces;
  std::vector<Vector3d> positions;
  for (int f : faces) {
    Tri lt;
    for (int k = 0; k < 3; ++k) {
      const int v = mesh.triangles[f][k];
      if (local_of[v] < 0) {
        local_of[v] = static_cast<int>(chart.vertices.size());
        chart.vertices.push_back(v);
        positions.push_back(mesh.positions[v].cast<double>());
      }
      lt[k] = local_of[v];
    }
    chart.local_triangles.push_back(lt);
  }
  for (int v : chart.vertices) local_of[v] = -1;

  if (faces.size() == 1) {  // one triangle: its own shape, exactly
    const Vector3d e1 = positions[1] - positions[0], e2 = positions[2] - positions[0];
    const double l1 = e1.norm();
    if (!(e1.cross(e2).norm() > 0) || !(l1 > 0)) {
      // A degenerate triangle (no area, so no texels): a point chart; it only takes a gutter.
      chart.uv.assign(3, Vector2d::Zero());
      *out = std::move(chart);
      return true;
    }
    chart.uv = {Vector2d::Zero(), Vector2d(l1, 0), Vector2d(e2.dot(e1) / l1, e1.cross(e2).norm() / l1)};
  } else if (!flatten_chart(positions, chart.local_triangles, method, &chart.uv)) {
    return false;
  }
  // Orientation: counter-clockwise in the plane, as on the surface seen from outside.
  double signed_area = 0;
  for (const Tri& t : chart.local_triangles) {
    const Vector2d a = chart.uv[t[1]] - chart.uv[t[0]], b = chart.uv[t[2]] - chart.uv[t[0]];
    signed_area += 0.5 * (a.x() * b.y() - a.y() * b.x());
  }
  if (!(std::abs(signed_area) > 0)) return false;
  if (signed_area < 0) {
    for (Vector2d& q : chart.uv) q.x() = -q.x();
  }
  int flipped = 0;
  chart.stretch = l2_stretch(positions, chart.uv, chart.local_triangles, &flipped);
  if (flipped > 0 || !(chart.stretch <= options.max_stretch)) return false;

  // Plane area = surface area, principal axis along x, box corner at the origin.
  double area3 = 0;
  for (const Tri& t : chart.local_triangles) {
    area3 += 0.5 * (positions[t[1]] - positions[t[0]]).cross(positions[t[2]] - positions[t[0]]).norm();
  }
  chart.area = area3;
  const double scale = std::sqrt(area3 / std::abs(signed_area));
  Vector2d mean = Vector2d::Zero();
  for (Vector2d& q : chart.uv) {
    q *= scale;
    mean += q;
  }
  mean /= static_cast<double>(chart.uv.size());
  Eigen::Matrix2d cov = Eigen::Matrix2d::Zero();
  for (const Vector2d& q : chart.uv) cov += (q - mean) * (q - mean).transpose();
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> eig(cov);
  Eigen::Matrix2d rotation;
  rotation.row(0) = eig.eigenvectors().col(1).transpose();  // major axis -> x
  rotation.row(1) = eig.eigenvectors().col(0).transpose();
  if (rotation.determinant() < 0) rotation.row(1) *= -1;  // a rotation, not a mirror
  Vector2d lo = Vector2d::Constant(std::numeric_limits<double>::max()), hi = -lo;
  for (Vector2d& q : chart.uv) {
    q = rotation * (q - mean);
    lo = lo.cwiseMin(q);
    hi = hi.cwiseMax(q);
  }
  for (Vector2d& q : chart.uv) q -= lo;
  chart.size = hi - lo;
  *out = std::move(chart);
  return true;
}

// Shelf packing of boxes (sizes in metres, sorted by decreasing height) at `scale` texels per
// metre; false when they do not fit. `offsets` gets the texel corner of each chart.
bool pack(const std::vector<FlatChart>& charts, double scale, int resolution, int gutter,
          std::vector<Vector2d>* offsets) {
  offsets->resize(charts.size());
  double x = 0, y = 0, shelf = 0;
  for (std::size_t i = 0; i < charts.size(); ++i) {
    const double w = std::ceil(charts[i].size.x() * scale) + gutter;
    const double h = std::ceil(charts[i].size.y() * scale) + gutter;
    if (w > resolution) return false;
    if (x + w > resolution) {
      y += shelf;
      x = 0;
      shelf = 0;
    }
    (*offsets)[i] = Vector2d(x + 0.5 * gutter, y + 0.5 * gutter);
    x += w;
    shelf = std::max(shelf, h);
  }
  return y + shelf <= resolution;
}


}  // namespace

std::vector<std::array<int, 3>> face_neighbours(const std::vector<Tri>& triangles) {
  std::unordered_map<std::uint64_t, std::vector<std::pair<int, int>>> edges;
  edges.reserve(triangles.size() * 2);
  for (int f = 0; f < static_cast<int>(triangles.size()); ++f) {
    for (int k = 0; k < 3; ++k) {
      const auto [a, b] = std::minmax(triangles[f][k], triangles[f][(k + 1) % 3]);
      edges[(static_cast<std::uint64_t>(a) << 32) | static_cast<std::uint32_t>(b)].push_back({f, k});
    }
  }
  std::vector<std::array<int, 3>> out(triangles.size(), {-1, -1, -1});
  for (const auto& [key, faces] : edges) {
    if (faces.size() != 2) continue;
    out[faces[0].first][faces[0].second] = faces[1].first;
    out[faces[1].first][faces[1].second] = faces[0].first;
  }
  return out;
}

void AtlasOptions::check() const {
  parse_flatten_method(method, "method");
}

double l2_stretch(const std::vector<Vector3d>& positions, const std::vector<Vector2d>& uv,
                  const std::vector<Tri>& triangles, int* flipped) {
  double area3 = 0, area2 = 0;
  for (const Tri& t : triangles) {
    area3 += 0.5 * (positions[t[1]] - positions[t[0]]).cross(positions[t[2]] - positions[t[0]]).norm();
    const Vector2d a = uv[t[1]] - uv[t[0]], b = uv[t[2]] - uv[t[0]];
    area2 += 0.5 * std::abs(a.x() * b.y() - a.y() * b.x());
  }
  if (flipped) *flipped = 0;
  if (!(area2 > 0) || !(area3 > 0)) return std::numeric_limits<double>::infinity();
  const double k = std::sqrt(area3 / area2);  // plane scale that equalises the areas
  double sum = 0;
  for (const Tri& t : triangles) {
    const Vector3d& p0 = positions[t[0]];
    const Vector3d& p1 = positions[t[1]];
    const Vector3d& p2 = positions[t[2]];
    const Vector2d q0 = k * uv[t[0]], q1 = k * uv[t[1]], q2 = k * uv[t[2]];
    const double a2 = 0.5 * ((q1.x() - q0.x()) * (q2.y() - q0.y()) - (q2.x() - q0.x()) * (q1.y() - q0.y()));
    const double a3 = 0.5 * (p1 - p0).cross(p2 - p0).norm();
    if (!(a2 > 0)) {
      if (flipped) ++*flipped;
      if (a3 > 0) return std::numeric_limits<double>::infinity();
      continue;
    }
    const Vector3d ss = (p0 * (q1.y() - q2.y()) + p1 * (q2.y() - q0.y()) + p2 * (q0.y() - q1.y())) / (2 * a2);
    const Vector3d st = (p0 * (q2.x() - q1.x()) + p1 * (q0.x() - q2.x()) + p2 * (q1.x() - q0.x())) / (2 * a2);
    sum += a3 * 0.5 * (ss.squaredNorm() + st.squaredNorm());
  }
  return std::sqrt(sum / area3);
}

Atlas build_atlas(const Mesh& mesh, const AtlasOptions& options) {
  options.check();
  if (mesh.empty()) throw InputError("atlas: the mesh has no triangles");
  const FlattenMethod method = parse_flatten_method(options.method, "method");
  const FaceGeometry geometry = face_geometry(mesh);
  const auto neighbours = face_neighbours(mesh.triangles);

  Atlas atlas;
  atlas.resolution = options.resolution;
  atlas.gutter = options.gutter;
  std::vector<int> mark(mesh.triangles.size(), -1);
  std::vector<int> local_of(mesh.positions.size(), -1);
  std::deque<std::vector<int>> work;
  for (auto& chart : grow_charts(geometry, neighbours, options.max_chart_angle)) {
    work.push_back(std::move(chart));
  }
  std::vector<FlatChart> flat;
  while (!work.empty()) {
    std::vector<int> faces = std::move(work.front());
    work.pop_front();
    auto pieces = connected_pieces(faces, neighbours, mark);
    if (pieces.size() > 1) {
      for (auto& p : pieces) work.push_back(std::move(p));
      continue;
    }
    FlatChart chart;
    if (flatten(mesh, faces, options, method, local_of, &chart)) {
      flat.push_back(std::move(chart));
      continue;
    }
    if (faces.size() == 1) {
      throw SolverError(fmt::format("atlas: face {} cannot be flattened (degenerate triangle)",
                                    faces.front()));
    }
    ++atlas.splits;
    auto [a, b] = split_faces(faces, geometry);
    work.push_back(std::move(a));
    work.push_back(std::move(b));
  }

  // Pack: tallest first, then the largest density at which every chart fits.
  std::sort(flat.begin(), flat.end(),
            [](const FlatChart& a, const FlatChart& b) { return a.size.y() > b.size.y(); });
  double total_area = 0;
  for (const FlatChart& c : flat) total_area += c.area;
  std::vector<Vector2d> offsets;
  double hi = options.resolution / std::sqrt(total_area);  // a perfect packing without gutters
  double lo = 0;
  if (!pack(flat, 1e-9, options.resolution, options.gutter, &offsets)) {
    throw ConfigError(fmt::format(
        "atlas: {} charts with {}-texel gutters do not fit in {}x{} texels; raise resolution",
        flat.size(), options.gutter, options.resolution, options.resolution));
  }
  for (int it = 0; it < 40; ++it) {
    const double mid = 0.5 * (lo + hi);
    (pack(flat, mid, options.resolution, options.gutter, &offsets) ? lo : hi) = mid;
  }
  pack(flat, lo, options.resolution, options.gutter, &offsets);
  atlas.texels_per_metre = lo;

  const int nf = static_cast<int>(mesh.triangles.size());
  atlas.uv_triangles.assign(nf, Tri::Constant(-1));
  atlas.face_chart.assign(nf, -1);
  double weighted = 0;
  for (std::size_t c = 0; c < flat.size(); ++c) {
    const FlatChart& fc = flat[c];
    Chart chart;
    chart.faces = fc.faces;
    chart.offset = offsets[c];
    chart.size = fc.size * lo;
    chart.area = fc.area;
    chart.stretch = fc.stretch;
    const int base = static_cast<int>(atlas.uvs.size());
    for (const Vector2d& q : fc.uv) {
      // y flips: texel rows run down, v runs up, so the chart stays counter-clockwise in UV.
      const Vector2d texel = offsets[c] + lo * Vector2d(q.x(), fc.size.y() - q.y());
      atlas.uvs.emplace_back(static_cast<float>(texel.x() / options.resolution),
                             static_cast<float>(1.0 - texel.y() / options.resolution));
    }
    for (std::size_t i = 0; i < fc.faces.size(); ++i) {
      atlas.uv_triangles[fc.faces[i]] = fc.local_triangles[i] + Tri::Constant(base);
      atlas.face_chart[fc.faces[i]] = static_cast<int>(c);
    }
    weighted += fc.area * fc.stretch * fc.stretch;
    atlas.max_stretch = std::max(atlas.max_stretch, fc.stretch);
    atlas.charts.push_back(std::move(chart));
  }
  atlas.stretch = std::sqrt(weighted / total_area);
  // Flips after packing (float rounding of tiny triangles), counted in texel space (y down:
  // counter-clockwise on the surface is clockwise in texel coordinates).
  for (int f = 0; f < nf; ++f) {
    const Tri& t = atlas.uv_triangles[f];
    const Vector2d a = atlas.texel(atlas.uvs[t[0]]), b = atlas.texel(atlas.uvs[t[1]]),
                   c = atlas.texel(atlas.uvs[t[2]]);
    const double cross = (b - a).x() * (c - a).y() - (b - a).y() * (c - a).x();
    if (cross >= 0 && geometry.area[f] > 0) ++atlas.flipped_faces;
  }
  return atlas;
}

Mesh with_atlas_uvs(const Mesh& mesh, const Atlas& atlas) {
  Mesh out;
  out.positions = mesh.positions;
  out.triangles = mesh.triangles;
  out.normals = mesh.normals;
  out.uvs = atlas.uvs;
  out.uv_triangles = atlas.uv_triangles;
  return out;
}


}  // namespace fourd::texture
