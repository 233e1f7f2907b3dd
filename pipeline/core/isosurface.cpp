#include "pipeline/core/isosurface.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <unordered_map>

#include <tbb/parallel_for.h>

namespace fourd {
namespace {

// Cube corners as bit offsets (x, y, z), corner c = x + 2y + 4z.
constexpr std::array<std::array<int, 3>, 8> kCorner = {{{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {1, 1, 0},
                                                       {0, 0, 1}, {1, 0, 1}, {0, 1, 1}, {1, 1, 1}}};
// Freudenthal split: the 6 tetrahedra around the main diagonal 0-7. Consistent between
// neighbouring cubes, so shared faces are split the same way and the surface is closed.
constexpr std::array<std::array<int, 4>, 6> kTets = {{{0, 1, 3, 7}, {0, 3, 2, 7}, {0, 2, 6, 7},
                                                     {0, 6, 4, 7}, {0, 4, 5, 7}, {0, 5, 1, 7}}};

class Extractor {
 public:
  Extractor(const ScalarGrid& grid, float iso) : grid_(grid), iso_(iso) {}

  Mesh run() {
    for (int z = -1; z < grid_.nz; ++z) {
      for (int y = -1; y < grid_.ny; ++y) {
        for (int x = -1; x < grid_.nx; ++x) cube(x, y, z);
      }
    }
    return std::move(mesh_);
  }

 private:
  // Samples outside the grid (and NaN) are "outside" by one voxel, as a signed distance would
  // be: the surface closes at the border.
  float value(int x, int y, int z) const {
    const float outside = static_cast<float>(grid_.voxel);
    if (x < 0 || y < 0 || z < 0 || x >= grid_.nx || y >= grid_.ny || z >= grid_.nz) return outside;
    float v = grid_.at(x, y, z);
    return std::isnan(v) ? outside : v - iso_;
  }

  static std::int64_t key(int x, int y, int z) {
    return ((static_cast<std::int64_t>(z) + 2) << 42) | ((static_cast<std::int64_t>(y) + 2) << 21) |
           (static_cast<std::int64_t>(x) + 2);
  }

  void cube(int x, int y, int z) {
    std::array<float, 8> v;
    bool any_in = false, any_out = false;
    for (int c = 0; c < 8; ++c) {
      v[c] = value(x + kCorner[c][0], y + kCorner[c][1], z + kCorner[c][2]);
      (v[c] < 0 ? any_in : any_out) = true;
    }
    if (!any_in || !any_out) return;
    for (const auto& tet : kTets) tetrahedron(x, y, z, tet, v);
  }

  // Vertex on the grid edge between corners a and b of cube (x,y,z), shared by every
  // tetrahedron and cube that uses that edge.
  int edge_vertex(int x, int y, int z, int a, int b, const std::array<float, 8>& v) {
    std::int64_t ka = key(x + kCorner[a][0], y + kCorner[a][1], z + kCorner[a][2]);
    std::int64_t kb = key(x + kCorner[b][0], y + kCorner[b][1], z + kCorner[b][2]);
    if (ka > kb) {
      std::swap(ka, kb);
      std::swap(a, b);
    }
    auto [it, inserted] = vertices_.try_emplace(std::make_pair(ka, kb), 0);
    if (!inserted) return it->second;
    float t = v[a] / (v[a] - v[b]);
    Eigen::Vector3d pa = grid_.point(x + kCorner[a][0], y + kCorner[a][1], z + kCorner[a][2]);
    Eigen::Vector3d pb = grid_.point(x + kCorner[b][0], y + kCorner[b][1], z + kCorner[b][2]);
    it->second = static_cast<int>(mesh_.positions.size());
    mesh_.positions.push_back((pa + t * (pb - pa)).cast<float>());
    return it->second;
  }

  static Eigen::Vector3d corner(int c) {
    return Eigen::Vector3d(kCorner[c][0], kCorner[c][1], kCorner[c][2]);
  }
  // Midpoint of the cube edge a-b: orientation is decided on these, never on the interpolated
  // positions, which may coincide when a sample equals the iso value.
  static Eigen::Vector3d mid(int a, int b) { return 0.5 * (corner(a) + corner(b)); }

  // Triangle of vertices i, j, k lying on the edges ea, eb, ec (pairs of cube corners).
  void emit(int i, int j, int k, const std::array<std::pair<int, int>, 3>& edges,
            const Eigen::Vector3d& outward) {
    Eigen::Vector3d a = mid(edges[0].first, edges[0].second);
    Eigen::Vector3d b = mid(edges[1].first, edges[1].second);
    Eigen::Vector3d c = mid(edges[2].first, edges[2].second);
    if ((b - a).cross(c - a).dot(outward) < 0) std::swap(j, k);
    if (i == j || j == k || i == k) return;
    mesh_.triangles.emplace_back(i, j, k);
  }

  void tetrahedron(int x, int y, int z, const std::array<int, 4>& tet, const std::array<float, 8>& v) {
    std::array<int, 4> in, out;
    int n_in = 0, n_out = 0;
    for (int c : tet) (v[c] < 0 ? in[n_in++] : out[n_out++]) = c;
    if (n_in == 0 || n_out == 0) return;
    // Outward = from the inside corners towards the outside corners.
    Eigen::Vector3d cin = Eigen::Vector3d::Zero(), cout = Eigen::Vector3d::Zero();
    for (int i = 0; i < n_in; ++i) cin += corner(in[i]);
    for (int i = 0; i < n_out; ++i) cout += corner(out[i]);
    Eigen::Vector3d outward = cout / n_out - cin / n_in;
    if (n_in == 1 || n_in == 3) {
      int apex = n_in == 1 ? in[0] : out[0];
      const auto& others = n_in == 1 ? out : in;
      int a = edge_vertex(x, y, z, apex, others[0], v);
      int b = edge_vertex(x, y, z, apex, others[1], v);
      int c = edge_vertex(x, y, z, apex, others[2], v);
      emit(a, b, c, {{{apex, others[0]}, {apex, others[1]}, {apex, others[2]}}}, outward);
    } else {
      // Quad across the four edges in0-out0, in0-out1, in1-out1, in1-out0.
      int a = edge_vertex(x, y, z, in[0], out[0], v);
      int b = edge_vertex(x, y, z, in[0], out[1], v);
      int c = edge_vertex(x, y, z, in[1], out[1], v);
      int d = edge_vertex(x, y, z, in[1], out[0], v);
      emit(a, b, c, {{{in[0], out[0]}, {in[0], out[1]}, {in[1], out[1]}}}, outward);
      emit(a, c, d, {{{in[0], out[0]}, {in[1], out[1]}, {in[1], out[0]}}}, outward);
    }
  }

  struct PairHash {
    std::size_t operator()(const std::pair<std::int64_t, std::int64_t>& p) const {
      return std::hash<std::int64_t>()(p.first * 0x9E3779B97F4A7C15ull ^ p.second);
    }
  };

  const ScalarGrid& grid_;
  float iso_;
  Mesh mesh_;
  std::unordered_map<std::pair<std::int64_t, std::int64_t>, int, PairHash> vertices_;
};

// The grid's trilinear interpolation and its gradient at `p`; false when p's cell lies beyond
// the grid or holds a NaN sample.
bool trilinear(const ScalarGrid& grid, const Eigen::Vector3d& p, double& value,
               Eigen::Vector3d& gradient) {
  const Eigen::Vector3d g = (p - grid.origin) / grid.voxel;
  // Checked before the conversion to int (a NaN or far-away point must not reach it).
  if (!(g.x() >= 0 && g.y() >= 0 && g.z() >= 0 && g.x() < grid.nx - 1 && g.y() < grid.ny - 1 &&
        g.z() < grid.nz - 1)) {
    return false;
  }
  const int x = static_cast<int>(g.x()), y = static_cast<int>(g.y()), z = static_cast<int>(g.z());
  const double tx = g.x() - x, ty = g.y() - y, tz = g.z() - z;
  std::array<double, 8> v;
  for (int c = 0; c < 8; ++c) {
    v[c] = grid.at(x + kCorner[c][0], y + kCorner[c][1], z + kCorner[c][2]);
    if (std::isnan(v[c])) return false;
  }
  // Along x first (corner c = x + 2y + 4z), then y, then z.
  const double v00 = v[0] + tx * (v[1] - v[0]), v10 = v[2] + tx * (v[3] - v[2]);
  const double v01 = v[4] + tx * (v[5] - v[4]), v11 = v[6] + tx * (v[7] - v[6]);
  const double v0 = v00 + ty * (v10 - v00), v1 = v01 + ty * (v11 - v01);
  value = v0 + tz * (v1 - v0);
  const double dx00 = v[1] - v[0], dx10 = v[3] - v[2], dx01 = v[5] - v[4], dx11 = v[7] - v[6];
  const double dx0 = dx00 + ty * (dx10 - dx00), dx1 = dx01 + ty * (dx11 - dx01);
  gradient = Eigen::Vector3d(dx0 + tz * (dx1 - dx0), (v10 - v00) + tz * ((v11 - v01) - (v10 - v00)),
                             v1 - v0) /
             grid.voxel;
  return true;
}

}  // namespace

Mesh extract_isosurface(const ScalarGrid& grid, float iso) { return Extractor(grid, iso).run(); }

ScalarGrid subsample(const ScalarGrid& grid, int step) {
  if (step <= 1) return grid;
  ScalarGrid out;
  out.origin = grid.origin;
  out.voxel = grid.voxel * step;
  out.nx = (grid.nx - 1) / step + 1;
  out.ny = (grid.ny - 1) / step + 1;
  out.nz = (grid.nz - 1) / step + 1;
  out.values.resize(static_cast<std::size_t>(out.nx) * out.ny * out.nz);
  tbb::parallel_for(0, out.nz, [&](int z) {
    for (int y = 0; y < out.ny; ++y)
      for (int x = 0; x < out.nx; ++x)
        out.values[out.index(x, y, z)] = grid.at(x * step, y * step, z * step);
  });
  return out;
}

int project_to_isosurface(Mesh& mesh, const ScalarGrid& grid, float iso, double max_move) {
  constexpr int kSteps = 8;
  const double tolerance = 0.1 * grid.voxel;
  const std::vector<Vec3f> before = mesh.positions;
  int moved = 0;
  for (Vec3f& vertex : mesh.positions) {
    const Eigen::Vector3d start = vertex.cast<double>();
    Eigen::Vector3d p = start;
    bool reached = false;
    for (int step = 0; step <= kSteps; ++step) {
      double value;
      Eigen::Vector3d gradient;
      if (!trilinear(grid, p, value, gradient)) break;
      const double f = value - iso;
      if (std::fabs(f) <= 1e-3 * tolerance) {
        reached = true;
        break;
      }
      if (step == kSteps) {
        reached = std::fabs(f) / std::max(gradient.norm(), 1e-12) <= tolerance;
        break;
      }
      const double g2 = gradient.squaredNorm();
      if (!(g2 > 1e-12)) break;
      Eigen::Vector3d delta = -f / g2 * gradient;
      if (delta.norm() > grid.voxel) delta *= grid.voxel / delta.norm();
      p += delta;
      if ((p - start).norm() > max_move) break;
    }
    if (reached && p != start) {
      vertex = p.cast<float>();
      ++moved;
    }
  }
  // Each vertex moved on its own: where the level set bends within a triangle's span, the
  // triangle can fold over. Its vertices go back where they were, until no triangle is folded.
  auto normal = [&](const std::vector<Vec3f>& v, const Tri& t) {
    return (v[t[1]] - v[t[0]]).cross(v[t[2]] - v[t[0]]);
  };
  for (bool reverted = true; reverted;) {
    reverted = false;
    for (const Tri& t : mesh.triangles) {
      if (normal(before, t).dot(normal(mesh.positions, t)) >= 0) continue;
      for (int k = 0; k < 3; ++k) {
        if (mesh.positions[t[k]] == before[t[k]]) continue;
        mesh.positions[t[k]] = before[t[k]];
        --moved;
        reverted = true;
      }
    }
  }
  return moved;
}

}  // namespace fourd
