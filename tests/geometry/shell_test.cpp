#include "pipeline/geometry/shell.h"

#include <gtest/gtest.h>

#include <cmath>
#include <numbers>

#include "pipeline/core/error.h"
#include "pipeline/geometry/measures.h"
#include "pipeline/geometry/repair.h"

namespace fourd {
namespace {

// A cylinder of radius r from z = 0 down to z = -h: rings running down, columns
// counterclockwise seen from above (the outside away from the axis).
std::vector<Eigen::Vector3d> cylinder(const TubeGrid& grid, double r, double h) {
  std::vector<Eigen::Vector3d> sheet;
  for (int ring = 0; ring < grid.rings; ++ring) {
    for (int c = 0; c < grid.columns; ++c) {
      const double a = 2 * std::numbers::pi * c / grid.columns;
      sheet.emplace_back(r * std::cos(a), r * std::sin(a), -h * ring / (grid.rings - 1));
    }
  }
  return sheet;
}

TEST(TubeShell, ClosesACylinderIntoAnOutwardShellOfItsThickness) {
  const TubeGrid grid{12, 96};
  const double r = 0.3, h = 0.5, t = 0.01;
  Mesh shell;
  shell.triangles = tube_shell_triangles(grid);
  shell.positions = tube_shell_positions(grid, cylinder(grid, r, h), t);
  ASSERT_EQ(shell.num_vertices(), 2u * 12 * 96);
  EXPECT_EQ(shell.num_triangles(), 4u * 96 * 12);
  const ManifoldReport report = check_manifold(shell);
  EXPECT_TRUE(report.manifold());
  EXPECT_EQ(report.boundary_edges, 0);
  EXPECT_EQ(report.components, 1);
  EXPECT_EQ(report.handles, 1);  // a torus
  // Outward: the volume is positive, about the wall's (the polygon is a little inside the circle).
  const double wall = std::numbers::pi * ((r + t / 2) * (r + t / 2) - (r - t / 2) * (r - t / 2)) * h;
  EXPECT_NEAR(enclosed_volume(shell), wall, 0.01 * wall);
  // The outer side first, half the thickness out; the inner side half of it in.
  for (int i = 0; i < grid.size(); ++i) {
    EXPECT_NEAR(shell.positions[static_cast<std::size_t>(i)].head<2>().norm(), r + t / 2, 1e-6);
    EXPECT_NEAR(shell.positions[static_cast<std::size_t>(grid.size() + i)].head<2>().norm(), r - t / 2, 1e-6);
  }
}

TEST(TubeShell, DegenerateNeighboursFallBackToTheRingsCentroid) {
  const TubeGrid grid{3, 8};
  std::vector<Eigen::Vector3d> sheet = cylinder(grid, 0.2, 0.2);
  // Ring 1 collapsed onto ring 0 and ring 2 for column 0: along the column the neighbours
  // coincide.
  sheet[static_cast<std::size_t>(grid.index(2, 0))] = sheet[static_cast<std::size_t>(grid.index(0, 0))];
  const std::vector<Vec3f> shell = tube_shell_positions(grid, sheet, 0.02);
  const Vec3f outer = shell[static_cast<std::size_t>(grid.index(1, 0))];
  const Vec3f inner = shell[static_cast<std::size_t>(grid.size() + grid.index(1, 0))];
  EXPECT_TRUE(outer.allFinite() && inner.allFinite());
  EXPECT_GT(outer.x(), inner.x());  // column 0 is at +x: out is +x
  EXPECT_NEAR((outer - inner).norm(), 0.02, 1e-6);
}

// A tube flattened until its two halves are nearer than the shell is thick (cloth folded onto
// itself): offset by half the thickness either way, the sides would pass through each other.
// The shell thins there to stay within the gap, and keeps its thickness where the sheet is
// clear of itself.
TEST(TubeShell, ThinsWhereTheSheetFoldsOntoItself) {
  const TubeGrid grid{6, 96};
  const double t = 0.01, a = 0.1, b = 0.003;  // the halves 6 mm apart
  std::vector<Eigen::Vector3d> sheet;
  for (int ring = 0; ring < grid.rings; ++ring) {
    for (int c = 0; c < grid.columns; ++c) {
      const double angle = 2 * std::numbers::pi * c / grid.columns;
      sheet.emplace_back(a * std::cos(angle), b * std::sin(angle), -0.2 * ring / (grid.rings - 1));
    }
  }
  Mesh shell;
  shell.triangles = tube_shell_triangles(grid);
  shell.positions = tube_shell_positions(grid, sheet, t);
  EXPECT_FALSE(has_self_intersections(shell));
  EXPECT_GT(enclosed_volume(shell), 0.0);
  const int n = grid.size();
  for (int i = 0; i < n; ++i) {
    const float thickness = (shell.positions[static_cast<std::size_t>(i)] - shell.positions[static_cast<std::size_t>(n + i)]).norm();
    EXPECT_LT(thickness, 2 * b) << i;  // within the gap between the halves
    EXPECT_GT(thickness, 0.0f) << i;
  }
  // Clear of itself (a round tube of the same grid), the shell is as thick as asked.
  sheet.clear();
  for (int ring = 0; ring < grid.rings; ++ring) {
    for (int c = 0; c < grid.columns; ++c) {
      const double angle = 2 * std::numbers::pi * c / grid.columns;
      sheet.emplace_back(a * std::cos(angle), a * std::sin(angle), -0.2 * ring / (grid.rings - 1));
    }
  }
  const std::vector<Vec3f> round = tube_shell_positions(grid, sheet, t);
  for (int i = 0; i < n; ++i) {
    EXPECT_NEAR((round[static_cast<std::size_t>(i)] - round[static_cast<std::size_t>(n + i)]).norm(), t, 1e-6);
  }
}

TEST(TubeShell, RejectsTooSmallGrids) {
  EXPECT_THROW(tube_shell_triangles(TubeGrid{1, 8}), InputError);
  EXPECT_THROW(tube_shell_triangles(TubeGrid{4, 2}), InputError);
  EXPECT_THROW(tube_shell_positions(TubeGrid{4, 8}, std::vector<Eigen::Vector3d>(5), 0.01), InputError);
}

}  // namespace
}  // namespace fourd
