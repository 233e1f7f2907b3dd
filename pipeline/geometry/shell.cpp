#include "pipeline/geometry/shell.h"

#include <fmt/format.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cstdint>
#include <utility>

#include "pipeline/core/error.h"

namespace fourd {

int TubeGrid::steps(int i, int j) const {
  const int dr = std::abs(i / columns - j / columns), dc = std::abs(i % columns - j % columns);
  return std::max(dr, std::min(dc, columns - dc));
}

std::vector<Tri> TubeGrid::sheet_triangles() const {
  std::vector<Tri> out;
  for (int r = 0; r + 1 < rings; ++r) {
    for (int c = 0; c < columns; ++c) {
      const int a = index(r, c), b = index(r, (c + 1) % columns);
      const int d = index(r + 1, c), e = index(r + 1, (c + 1) % columns);
      out.emplace_back(a, d, e);
      out.emplace_back(a, e, b);
    }
  }
  return out;
}

namespace {

// Where the sheet bends sharply, each side keeps at most this share of the sheet's radius of
// curvature from it; where other parts of the sheet come near, at most this share of the
// distance to them.
constexpr double kBendShare = 0.5;
constexpr double kGapShare = 0.45;
// The sheet lies over a triangle where the nearest point of it is within this cosine of its
// normal.
constexpr double kOver = 0.9;

// The point of the triangle (a, b, c) nearest to p (Ericson, "Real-Time Collision Detection",
// 5.1.5).
Eigen::Vector3d closest_on_triangle(const Eigen::Vector3d& p, const Eigen::Vector3d& a, const Eigen::Vector3d& b,
                                    const Eigen::Vector3d& c) {
  const Eigen::Vector3d ab = b - a, ac = c - a, ap = p - a;
  const double d1 = ab.dot(ap), d2 = ac.dot(ap);
  if (d1 <= 0 && d2 <= 0) return a;
  const Eigen::Vector3d bp = p - b;
  const double d3 = ab.dot(bp), d4 = ac.dot(bp);
  if (d3 >= 0 && d4 <= d3) return b;
  const double vc = d1 * d4 - d3 * d2;
  if (vc <= 0 && d1 >= 0 && d3 <= 0) return a + d1 / (d1 - d3) * ab;
  const Eigen::Vector3d cp = p - c;
  const double d5 = ab.dot(cp), d6 = ac.dot(cp);
  if (d6 >= 0 && d5 <= d6) return c;
  const double vb = d5 * d2 - d1 * d6;
  if (vb <= 0 && d2 >= 0 && d6 <= 0) return a + d2 / (d2 - d6) * ac;
  const double va = d3 * d6 - d5 * d4;
  if (va <= 0 && d4 - d3 >= 0 && d5 - d6 >= 0) return b + (d4 - d3) / ((d4 - d3) + (d5 - d6)) * (c - b);
  const double denominator = 1 / (va + vb + vc);
  return a + ab * (vb * denominator) + ac * (vc * denominator);
}

// Per point of the sheet, the distance to the nearest triangle of the sheet that has neither
// the point nor a neighbour of it (along its ring, its column or diagonally) as a corner, if
// nearer than `within`; `within` otherwise.
std::vector<double> gap_to_other_parts(const TubeGrid& grid, const std::vector<Eigen::Vector3d>& sheet, double within) {
  const int n = grid.size();
  std::vector<double> gap(static_cast<std::size_t>(n), within);
  // The sheet's points in cells of side `within`, sorted by cell.
  auto cell_of = [&](const Eigen::Vector3d& p) { return Eigen::Vector3i((p / within).array().floor().cast<int>()); };
  auto key = [](const Eigen::Vector3i& c) {
    return (static_cast<std::int64_t>(c.x() + (1 << 20)) << 42) | (static_cast<std::int64_t>(c.y() + (1 << 20)) << 21) |
           static_cast<std::int64_t>(c.z() + (1 << 20));
  };
  std::vector<std::pair<std::int64_t, int>> cells(static_cast<std::size_t>(n));
  for (int i = 0; i < n; ++i) cells[static_cast<std::size_t>(i)] = {key(cell_of(sheet[static_cast<std::size_t>(i)])), i};
  std::sort(cells.begin(), cells.end());
  for (const Tri& t : grid.sheet_triangles()) {
    const Eigen::Vector3d &p0 = sheet[static_cast<std::size_t>(t[0])], &p1 = sheet[static_cast<std::size_t>(t[1])],
                          &p2 = sheet[static_cast<std::size_t>(t[2])];
    Eigen::Vector3d normal = (p1 - p0).cross(p2 - p0);
    if (normal.norm() > 1e-12) normal.normalize();
    const Eigen::Vector3i lo = cell_of(p0.cwiseMin(p1).cwiseMin(p2) - Eigen::Vector3d::Constant(within));
    const Eigen::Vector3i hi = cell_of(p0.cwiseMax(p1).cwiseMax(p2) + Eigen::Vector3d::Constant(within));
    for (int x = lo.x(); x <= hi.x(); ++x) {
      for (int y = lo.y(); y <= hi.y(); ++y) {
        for (int z = lo.z(); z <= hi.z(); ++z) {
          const std::int64_t k = key({x, y, z});
          for (auto it = std::lower_bound(cells.begin(), cells.end(), std::make_pair(k, -1));
               it != cells.end() && it->first == k; ++it) {
            const int i = it->second;
            const int near = std::min({grid.steps(i, t[0]), grid.steps(i, t[1]), grid.steps(i, t[2])});
            if (near == 0) continue;
            const Eigen::Vector3d& p = sheet[static_cast<std::size_t>(i)];
            const Eigen::Vector3d to = closest_on_triangle(p, p0, p1, p2) - p;
            // A neighbour's triangle counts where the sheet lies over it (folded onto it),
            // not beside it (a cell's width away, its nearest point on its edge).
            if (near == 1 && std::abs(to.dot(normal)) < kOver * to.norm()) continue;
            double& g = gap[static_cast<std::size_t>(i)];
            g = std::min(g, to.norm());
          }
        }
      }
    }
  }
  return gap;
}

void require_grid(const TubeGrid& grid) {
  if (grid.rings < 2 || grid.columns < 3) {
    throw InputError(fmt::format("tube shell: needs at least 2 rings of 3 columns, not {} of {}",
                                 grid.rings, grid.columns));
  }
}

}  // namespace

std::vector<Tri> tube_shell_triangles(const TubeGrid& grid) {
  require_grid(grid);
  const int n = grid.size();
  auto outer = [&](int r, int c) { return grid.index(r, (c + grid.columns) % grid.columns); };
  auto inner = [&](int r, int c) { return n + outer(r, c); };
  std::vector<Tri> triangles;
  triangles.reserve(static_cast<std::size_t>(4 * grid.columns * grid.rings));
  for (int r = 0; r + 1 < grid.rings; ++r) {
    for (int c = 0; c < grid.columns; ++c) {
      // a, b along ring r, d, e below them on ring r + 1: seen from outside a is top left.
      const int a = outer(r, c), b = outer(r, c + 1), d = outer(r + 1, c), e = outer(r + 1, c + 1);
      triangles.emplace_back(a, d, e);
      triangles.emplace_back(a, e, b);
      const int ai = inner(r, c), bi = inner(r, c + 1), di = inner(r + 1, c), ei = inner(r + 1, c + 1);
      triangles.emplace_back(ai, ei, di);
      triangles.emplace_back(ai, bi, ei);
    }
  }
  // The rims: ring 0 faces away from the tube, the last ring along it.
  const int last = grid.rings - 1;
  for (int c = 0; c < grid.columns; ++c) {
    const int o0 = outer(0, c), o1 = outer(0, c + 1), i0 = inner(0, c), i1 = inner(0, c + 1);
    triangles.emplace_back(o0, o1, i1);
    triangles.emplace_back(o0, i1, i0);
    const int p0 = outer(last, c), p1 = outer(last, c + 1), j0 = inner(last, c), j1 = inner(last, c + 1);
    triangles.emplace_back(p0, j1, p1);
    triangles.emplace_back(p0, j0, j1);
  }
  return triangles;
}

std::vector<Vec3f> tube_shell_positions(const TubeGrid& grid, const std::vector<Eigen::Vector3d>& sheet,
                                        double thickness) {
  require_grid(grid);
  if (static_cast<int>(sheet.size()) != grid.size()) {
    throw InputError(fmt::format("tube shell: {} sheet points for a grid of {} x {}", sheet.size(),
                                 grid.rings, grid.columns));
  }
  const int n = grid.size();
  auto at = [&](int r, int c) -> const Eigen::Vector3d& {
    return sheet[static_cast<std::size_t>(grid.index(r, (c + grid.columns) % grid.columns))];
  };
  std::vector<Eigen::Vector3d> normals(static_cast<std::size_t>(n));
  for (int r = 0; r < grid.rings; ++r) {
    Eigen::Vector3d centroid = Eigen::Vector3d::Zero();
    for (int c = 0; c < grid.columns; ++c) centroid += at(r, c);
    centroid /= grid.columns;
    for (int c = 0; c < grid.columns; ++c) {
      const Eigen::Vector3d along = at(std::min(r + 1, grid.rings - 1), c) - at(std::max(r - 1, 0), c);
      const Eigen::Vector3d around = at(r, c + 1) - at(r, c - 1);
      Eigen::Vector3d normal = along.cross(around);
      if (normal.norm() < 1e-12) {
        const Eigen::Vector3d axis = along.norm() > 1e-12 ? along.normalized() : Eigen::Vector3d::Zero();
        normal = at(r, c) - centroid;
        normal -= normal.dot(axis) * axis;
      }
      if (normal.norm() > 1e-12) normal.normalize();
      normals[static_cast<std::size_t>(grid.index(r, c))] = normal;
    }
  }
  auto normal_at = [&](int r, int c) -> const Eigen::Vector3d& {
    return normals[static_cast<std::size_t>(grid.index(r, (c + grid.columns) % grid.columns))];
  };
  // The faces' normals summed at their corners (area-weighted): unlike the offset's normals,
  // they see the sheet fold along a cell's diagonal.
  std::vector<Eigen::Vector3d> face_normals(static_cast<std::size_t>(n), Eigen::Vector3d::Zero());
  for (const Tri& t : grid.sheet_triangles()) {
    const Eigen::Vector3d& p0 = sheet[static_cast<std::size_t>(t[0])];
    const Eigen::Vector3d f = (sheet[static_cast<std::size_t>(t[1])] - p0).cross(sheet[static_cast<std::size_t>(t[2])] - p0);
    for (int k = 0; k < 3; ++k) face_normals[static_cast<std::size_t>(t[k])] += f;
  }
  for (Eigen::Vector3d& f : face_normals) {
    if (f.norm() > 1e-12) f.normalize();
  }
  auto face_normal_at = [&](int r, int c) -> const Eigen::Vector3d& {
    return face_normals[static_cast<std::size_t>(grid.index(r, (c + grid.columns) % grid.columns))];
  };
  // Where other parts of the sheet come nearer than the shell is thick (the cloth folded onto
  // itself), the sides would pass through each other's: each side stays within kGapShare of
  // the gap.
  const std::vector<double> gap = gap_to_other_parts(grid, sheet, 0.5 * thickness / kGapShare);
  std::vector<Vec3f> out(static_cast<std::size_t>(2 * n));
  for (int r = 0; r < grid.rings; ++r) {
    for (int c = 0; c < grid.columns; ++c) {
      // Where the sheet bends more sharply than the shell is thick, its sides, offset by half
      // the thickness, would fold over each other. Between neighbours p and q (e = q - p) the
      // offset points p + h n_p and q + h n_q (and p - h n_p, q - h n_q) keep their order along
      // e while h |(n_q - n_p).e| < |e|^2: the sheet's radius of curvature between them (for a
      // circle of radius R, |e|^2 / |(n_q - n_p).e| = R). Each side stays within kBendShare of it.
      double half = std::min(0.5 * thickness, kGapShare * gap[static_cast<std::size_t>(grid.index(r, c))]);
      for (int dr = -1; dr <= 1; ++dr) {
        for (int dc = -1; dc <= 1; ++dc) {
          if ((dr == 0 && dc == 0) || r + dr < 0 || r + dr >= grid.rings) continue;
          const Eigen::Vector3d e = at(r + dr, c + dc) - at(r, c);
          const double turn = std::max(std::abs((normal_at(r + dr, c + dc) - normal_at(r, c)).dot(e)),
                                       std::abs((face_normal_at(r + dr, c + dc) - face_normal_at(r, c)).dot(e)));
          if (kBendShare * e.squaredNorm() < half * turn) half = kBendShare * e.squaredNorm() / turn;
        }
      }
      const Eigen::Vector3d offset = half * normal_at(r, c);
      out[static_cast<std::size_t>(grid.index(r, c))] = (at(r, c) + offset).cast<float>();
      out[static_cast<std::size_t>(n + grid.index(r, c))] = (at(r, c) - offset).cast<float>();
    }
  }
  return out;
}

}  // namespace fourd
