#include "stages/synth/garment.h"

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <map>
#include <opencv2/imgproc.hpp>

#include "pipeline/core/error.h"
#include "pipeline/geometry/measures.h"
#include "pipeline/geometry/mesh_query.h"
#include "pipeline/geometry/repair.h"
#include "stages/synth/motion.h"
#include "tests/synth/debug_render.h"
#include "tests/synth/motion_specs.h"

namespace fourd::synth {
namespace {

using test::dance;
using test::walk;

constexpr double kFps = 20;

CharacterOptions small_options() {
  CharacterOptions options;
  options.texture_size = 256;
  return options;
}

const Character& plain() {
  static const Character character = make_procedural_character(small_options(), 3);
  return character;
}

const Character& skirted() {
  static const Character character = [] {
    CharacterOptions options = small_options();
    options.garment = "skirt";
    return make_procedural_character(options, 3);
  }();
  return character;
}

struct Take {
  MotionClip clip;
  std::vector<Mesh> meshes;  // the performer's surface per frame
};

Take perform(const Character& character, const MotionSpec& spec) {
  Take take;
  take.clip = generate_motion(character.skeleton, spec, kFps);
  PerformerSurface surface(character, kFps);
  for (const Pose& pose : take.clip.poses) take.meshes.push_back(surface.next(pose));
  return take;
}

const Take& dance_take() {
  static const Take take = perform(skirted(), dance(180, 40));
  return take;
}

// The skirt's sheet in a frame: the middle of its shell's two sides, grid order.
std::vector<Eigen::Vector3d> sheet(const Character& c, const Mesh& mesh) {
  const Garment& g = *c.garment;
  const std::size_t first = c.skin.rest.num_vertices(), n = static_cast<std::size_t>(g.grid.size());
  std::vector<Eigen::Vector3d> out(n);
  for (std::size_t i = 0; i < n; ++i) {
    out[i] = 0.5 * (mesh.positions[first + i] + mesh.positions[first + n + i]).cast<double>();
  }
  return out;
}

Mesh body_part(const Character& c, const Mesh& mesh) {
  Mesh body;
  body.positions.assign(mesh.positions.begin(), mesh.positions.begin() + static_cast<long>(c.skin.rest.num_vertices()));
  body.triangles.assign(mesh.triangles.begin(), mesh.triangles.begin() + static_cast<long>(c.skin.rest.num_triangles()));
  return body;
}

// Every directed edge once, its reverse once: closed, manifold along edges, oriented.
bool closed_and_oriented(const std::vector<Tri>& triangles) {
  std::map<std::pair<int, int>, int> directed;
  for (const Tri& t : triangles) {
    for (int c = 0; c < 3; ++c) ++directed[{t[c], t[(c + 1) % 3]}];
  }
  for (const auto& [edge, count] : directed) {
    const auto reverse = directed.find({edge.second, edge.first});
    if (count != 1 || reverse == directed.end() || reverse->second != 1) return false;
  }
  return true;
}

// The heading of the skirt's hem and waistband about the waistband's centre: the mean over the
// columns of the angle from waist to hem about the vertical, in (-pi, pi] [rad].
double hem_twist(const Garment& g, const std::vector<Eigen::Vector3d>& s) {
  Eigen::Vector3d centre = Eigen::Vector3d::Zero();
  for (int c = 0; c < g.grid.columns; ++c) centre += s[static_cast<std::size_t>(c)];
  centre /= g.grid.columns;
  double sin_sum = 0, cos_sum = 0;
  for (int c = 0; c < g.grid.columns; ++c) {
    const Eigen::Vector3d w = s[static_cast<std::size_t>(c)] - centre;
    const Eigen::Vector3d h = s[static_cast<std::size_t>(g.grid.index(g.grid.rings - 1, c))] - centre;
    const double d = std::remainder(std::atan2(h.y(), h.x()) - std::atan2(w.y(), w.x()), 2 * M_PI);
    sin_sum += std::sin(d);
    cos_sum += std::cos(d);
  }
  return std::atan2(sin_sum, cos_sum);
}

double mean_hem_height(const Garment& g, const std::vector<Eigen::Vector3d>& s) {
  double z = 0;
  for (int c = 0; c < g.grid.columns; ++c) z += s[static_cast<std::size_t>(g.grid.index(g.grid.rings - 1, c))].z();
  return z / g.grid.columns;
}

// Without a garment nothing changes: the options' garment keys are ignored, the surface is the
// skin's, bit for bit, and the texture outside the skirt's chart is the same with a skirt.
TEST(Garment, NoneLeavesTheCharacterUnchanged) {
  CharacterOptions options = small_options();
  options.skirt_length = 0.7;
  options.skirt_flare = 20;
  const Character c = make_procedural_character(options, 3);
  EXPECT_FALSE(c.garment);
  EXPECT_EQ(c.skin.rest.positions, plain().skin.rest.positions);
  EXPECT_EQ(c.skin.rest.triangles, plain().skin.rest.triangles);
  EXPECT_EQ(cv::norm(c.texture, plain().texture, cv::NORM_INF), 0.0);
  const MotionClip clip = generate_motion(c.skeleton, walk(1.2, 6), kFps);
  PerformerSurface surface(c, kFps);
  for (const Pose& pose : clip.poses) {
    const Mesh a = surface.next(pose);
    const Mesh b = skin_mesh(c.skin, forward_kinematics(c.skeleton, pose));
    EXPECT_EQ(a.positions, b.positions);
    EXPECT_EQ(a.triangles, b.triangles);
    EXPECT_EQ(a.uvs, b.uvs);
  }
  EXPECT_EQ(rest_surface(c).positions, c.skin.rest.positions);

  // A skirt leaves the body and the rest of the texture alone.
  const Character& s = skirted();
  EXPECT_EQ(s.skin.rest.positions, plain().skin.rest.positions);
  cv::Mat difference;
  cv::absdiff(s.texture, plain().texture, difference);
  const int skirt_rows = static_cast<int>(std::ceil((1 - 0.61) * difference.rows));
  difference(cv::Rect(difference.cols / 2, 0, difference.cols / 4, skirt_rows)).setTo(cv::Scalar::all(0));
  EXPECT_EQ(cv::countNonZero(difference.reshape(1)), 0);

  CharacterOptions unknown = small_options();
  unknown.garment = "cape";
  EXPECT_THROW(make_procedural_character(unknown, 3), ConfigError);
}

TEST(Garment, SkirtIsAClosedShellOfOneTopologyInEveryFrame) {
  const Character& c = skirted();
  ASSERT_TRUE(c.garment);
  const Garment& g = *c.garment;
  EXPECT_EQ(g.grid.columns, 64);
  EXPECT_GE(g.grid.rings, 15);
  EXPECT_EQ(g.rest.num_vertices(), 2u * static_cast<std::size_t>(g.grid.size()));
  EXPECT_TRUE(closed_and_oriented(g.rest.triangles));
  EXPECT_GT(enclosed_volume(g.rest), 0.0);
  // About the shell's area times its thickness.
  EXPECT_NEAR(enclosed_volume(g.rest), 0.5 * surface_area(g.rest) * g.thickness, 0.2 * 0.5 * surface_area(g.rest) * g.thickness);
  const Mesh rest = rest_surface(c);
  EXPECT_EQ(rest.num_vertices(), c.skin.rest.num_vertices() + g.rest.num_vertices());
  EXPECT_EQ(rest.uvs.size(), rest.num_vertices());
  EXPECT_TRUE(closed_and_oriented(rest.triangles));
  for (const Vec2f& uv : g.rest.uvs) {
    EXPECT_GE(uv.x(), 0.5f);
    EXPECT_LT(uv.x(), 0.75f);
    EXPECT_GT(uv.y(), 0.62f);
  }
  for (const Mesh& m : dance_take().meshes) {
    EXPECT_EQ(m.triangles, rest.triangles);
    EXPECT_EQ(m.uvs, rest.uvs);
    ASSERT_EQ(m.num_vertices(), rest.num_vertices());
    for (const Vec3f& p : m.positions) ASSERT_TRUE(p.allFinite());
  }
  // Sized to the performer: the waist just above the belt, the hem a little above the knee.
  const double waist = mean_hem_height(g, g.cut) + g.length * std::cos(g.flare);
  EXPECT_NEAR(waist, 1.03, 0.02);
  EXPECT_NEAR(g.length, 0.45 * waist, 1e-9);
  EXPECT_NEAR(g.thickness, 0.010 * c.height / 1.75, 1e-12);
}

// The shell does not pass through itself: at rest, through the dance's first steps, and in
// the spin but for a few frames (without the cloth's contact with itself, the ring's limit on
// turning and the shell thinning where the cloth folds onto itself: 21 of the 40 frames, the
// sheet itself in 19). Crossing frames are counted on the shell (what validation re-meshes)
// and on the sheet (the simulation's particles as a surface: the middle of the two sides).
TEST(Garment, ShellHardlySelfIntersectsInASpin) {
  const Character& c = skirted();
  const Garment& g = *c.garment;
  EXPECT_FALSE(has_self_intersections(g.rest));
  const auto& meshes = dance_take().meshes;
  Mesh sheet_mesh;
  for (const Tri& t : g.rest.triangles) {
    if (t.maxCoeff() < g.grid.size()) sheet_mesh.triangles.push_back(t);  // the outer side's
  }
  int shell_crossing = 0, sheet_crossing = 0;
  for (std::size_t f = 0; f < meshes.size(); ++f) {
    Mesh shell;
    shell.positions.assign(meshes[f].positions.begin() + static_cast<long>(c.skin.rest.num_vertices()),
                           meshes[f].positions.end());
    shell.triangles = g.rest.triangles;
    const bool crosses = has_self_intersections(shell);
    if (f < 8) {
      EXPECT_FALSE(crosses) << "frame " << f;
    }
    shell_crossing += crosses;
    sheet_mesh.positions.clear();
    for (const Eigen::Vector3d& p : sheet(c, meshes[f])) sheet_mesh.positions.push_back(p.cast<float>());
    sheet_crossing += has_self_intersections(sheet_mesh);
  }
  printf("the shell passes through itself in %d of %zu frames, the sheet in %d\n", shell_crossing, meshes.size(),
         sheet_crossing);
  EXPECT_LE(shell_crossing, static_cast<int>(meshes.size()) / 4);
  EXPECT_LE(sheet_crossing, static_cast<int>(meshes.size()) / 10);
}

// Down the cloth the distances keep their cut length (inextensible), across it they never
// stretch (the waistband, ring 0, stretches with the skin it is sewn to), but where the body
// pushes the cloth out: a few percent at the most, over the fast dance.
TEST(Garment, ClothHardlyStretches) {
  const Character& c = skirted();
  const Garment& g = *c.garment;
  std::vector<double> down, across;
  for (const Mesh& m : dance_take().meshes) {
    const auto s = sheet(c, m);
    for (int r = 0; r + 1 < g.grid.rings; ++r) {
      for (int col = 0; col < g.grid.columns; ++col) {
        const auto i = static_cast<std::size_t>(g.grid.index(r, col));
        const auto below = static_cast<std::size_t>(g.grid.index(r + 1, col));
        const auto right = static_cast<std::size_t>(g.grid.index(r, (col + 1) % g.grid.columns));
        down.push_back((s[i] - s[below]).norm() / (g.cut[i] - g.cut[below]).norm() - 1);
        if (r > 0) across.push_back((s[i] - s[right]).norm() / (g.cut[i] - g.cut[right]).norm() - 1);
      }
    }
  }
  auto quantile = [](std::vector<double> v, double q) {
    std::sort(v.begin(), v.end());
    return v[static_cast<std::size_t>(q * static_cast<double>(v.size() - 1))];
  };
  printf("stretch down: median %.4f p99 %.4f max %.4f; across: p99 %.4f max %.4f\n", quantile(down, 0.5),
         quantile(down, 0.99), quantile(down, 1), quantile(across, 0.99), quantile(across, 1));
  EXPECT_LT(std::abs(quantile(down, 0.5)), 0.01);
  EXPECT_LT(quantile(down, 0.99), 0.04);
  EXPECT_LT(quantile(across, 0.99), 0.04);
  EXPECT_LT(quantile(down, 1), 0.15);
  EXPECT_LT(quantile(across, 1), 0.15);
}

// The shell stays off the skinned body (the surface that is rendered) over a dance and a fast
// walk: hardly a vertex of the skirt is inside the body, none deeper than 1 cm.
TEST(Garment, SkirtDoesNotPenetrateTheBody) {
  const Character& c = skirted();
  const Take walking = perform(c, walk(1.6, 30));
  const std::size_t first = c.skin.rest.num_vertices();
  for (const Take* take : {&dance_take(), &walking}) {
    double deepest = 0;
    int inside = 0, frames = 0;
    for (const Mesh& m : take->meshes) {
      const MeshQuery body(body_part(c, m));
      for (std::size_t v = first; v < m.num_vertices(); ++v) {
        const Vec3f& p = m.positions[v];
        const std::vector<MeshQuery::Crossing> xs = body.crossings_along_x(p.y(), p.z());
        const auto before = std::count_if(xs.begin(), xs.end(),
                                          [&](const MeshQuery::Crossing& x) { return x.x < p.x(); });
        if (before % 2 == 1) {
          ++inside;
          deepest = std::max(deepest, body.distance(p));
        }
      }
      ++frames;
    }
    const double vertices = static_cast<double>(frames) * static_cast<double>(c.garment->rest.num_vertices());
    EXPECT_LT(deepest, 0.01) << take->clip.spec.kind;
    EXPECT_LT(inside, 1e-3 * vertices) << take->clip.spec.kind << ": vertices inside over " << frames << " frames";
  }
}

// When the body turns, the skirt swings behind: as the spin speeds up the hem trails the
// waistband, then catches up and swings past it as the spin slows.
TEST(Garment, SkirtLagsBehindAspin) {
  const Character& c = skirted();
  const Garment& g = *c.garment;
  const Take& take = dance_take();
  double most_behind = 0, most_ahead = 0;
  int behind_frame = 0, ahead_frame = 0;
  for (std::size_t f = 0; f < take.meshes.size(); ++f) {
    const double twist = hem_twist(g, sheet(c, take.meshes[f]));
    if (twist < most_behind) most_behind = twist, behind_frame = static_cast<int>(f);
    if (twist > most_ahead) most_ahead = twist, ahead_frame = static_cast<int>(f);
  }
  printf("hem behind the waistband by %.1f deg (frame %d), ahead by %.1f deg (frame %d)\n", -most_behind * 180 / M_PI,
         behind_frame, most_ahead * 180 / M_PI, ahead_frame);
  // A left (counterclockwise) spin: behind is clockwise, negative.
  EXPECT_LT(most_behind, -10 * M_PI / 180);
  EXPECT_GT(most_ahead, 5 * M_PI / 180);
  EXPECT_LT(behind_frame, ahead_frame);
  EXPECT_NEAR(hem_twist(g, sheet(c, take.meshes.front())), 0.0, 2 * M_PI / 180);
}

// Spinning flares the skirt: the hem rises and moves out; the faster spin more.
TEST(Garment, HemRisesInASpin) {
  const Character& c = skirted();
  const Garment& g = *c.garment;
  auto rise = [&](const Take& take) {
    const double still = mean_hem_height(g, sheet(c, take.meshes.front()));
    double highest = still;
    for (const Mesh& m : take.meshes) highest = std::max(highest, mean_hem_height(g, sheet(c, m)));
    return highest - still;
  };
  const double fast = rise(dance_take());
  const double slow = rise(perform(c, dance(60, 40)));
  printf("hem rises by %.3f m in the fast spin, %.3f m in the slow one\n", fast, slow);
  EXPECT_GT(fast, 0.05);
  EXPECT_GT(fast, slow + 0.02);
  // Still, the hem hangs below the cut's cone: the skirt gathers.
  const auto still = sheet(c, dance_take().meshes.front());
  EXPECT_LT(mean_hem_height(g, still), mean_hem_height(g, g.cut) - 0.03);
}

TEST(Garment, Deterministic) {
  const Take again = perform(skirted(), dance(180, 40));
  ASSERT_EQ(again.meshes.size(), dance_take().meshes.size());
  for (std::size_t f = 0; f < again.meshes.size(); ++f) {
    EXPECT_EQ(again.meshes[f].positions, dance_take().meshes[f].positions) << f;
  }
}

TEST(Garment, DebugViews) {
  if (debug_view::debug_dir().empty()) GTEST_SKIP() << "set FOURD_SYNTH_DEBUG_DIR to write views";
  const Character& c = skirted();
  const Take& take = dance_take();
  std::vector<cv::Mat> views;
  for (std::size_t f = 0; f < take.meshes.size(); f += 5) {
    const Eigen::Vector3f centre(0, 0, 0.9f);
    views.push_back(debug_view::render_orthographic(take.meshes[f], c.texture, Eigen::Vector3f::UnitX(),
                                                    Eigen::Vector3f::UnitY(), centre, 120, 200, 240));
  }
  cv::Mat row;
  cv::hconcat(views, row);
  debug_view::write_debug_image("garment_dance.png", row);
}

}  // namespace
}  // namespace fourd::synth
