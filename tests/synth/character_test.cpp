#include "stages/synth/character.h"

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <map>
#include <opencv2/imgproc.hpp>
#include <set>

#include "pipeline/geometry/repair.h"
#include "tests/synth/debug_render.h"
#include "tests/synth/mesh_checks.h"

namespace fourd::synth {
namespace {

using test::expect_closed_manifold_sphere;
using test::fraction_near_hue;
using test::signed_volume;

const Character& default_character() {
  static const Character character = make_procedural_character(CharacterOptions{}, 1);
  return character;
}

// Before a blue screen the performer wears nothing blue (the sample's seed-2012 performer has a
// blue shirt and shoes); before the green screen the wardrobe is the one it always was.
TEST(Character, WardrobeKeepsTheStudiosKeyColourOutOfTheClothes) {
  const Eigen::Vector3d blue(25 / 255.0, 70 / 255.0, 185 / 255.0);
  const Eigen::Vector3d green(40 / 255.0, 170 / 255.0, 60 / 255.0);
  const Character any = make_procedural_character(CharacterOptions{}, 2012);
  const Character blue_screen = make_procedural_character(CharacterOptions{}, 2012, blue);
  const Character green_screen = make_procedural_character(CharacterOptions{}, 2012, green);
  const double blue_hue = 223;
  EXPECT_GT(fraction_near_hue(any.texture, blue_hue, 25), 0.05);
  EXPECT_LT(fraction_near_hue(blue_screen.texture, blue_hue, 25), 0.002);
  EXPECT_EQ(cv::norm(any.texture, green_screen.texture, cv::NORM_INF), 0.0);
}

TEST(Character, SkeletonIsAStandingHumanFacingForward) {
  const Skeleton& sk = default_character().skeleton;
  ASSERT_EQ(sk.size(), 21u);
  ASSERT_EQ(sk.parents.size(), sk.size());
  ASSERT_EQ(sk.rest_offsets.size(), sk.size());
  EXPECT_EQ(sk.parents[0], -1);
  for (std::size_t i = 1; i < sk.size(); ++i) EXPECT_LT(sk.parents[i], static_cast<int>(i)) << sk.names[i];
  for (const char* name : {"pelvis", "spine", "chest", "neck", "head", "clavicle_l", "upper_arm_r", "forearm_l",
                           "hand_r", "thigh_l", "shin_r", "foot_l", "toe_r"}) {
    EXPECT_GE(sk.find(name), 0) << name;
  }
  EXPECT_EQ(sk.find("tail"), -1);
  const auto world = forward_kinematics(sk, rest_pose(sk));
  auto at = [&](const char* name) { return world[static_cast<std::size_t>(sk.find(name))].translation(); };
  // At rest every joint frame is axis-aligned.
  for (const auto& w : world) EXPECT_TRUE(w.linear().isIdentity(1e-12));
  EXPECT_NEAR(at("pelvis").x(), 0, 1e-9);
  EXPECT_NEAR(at("pelvis").y(), 0, 1e-9);
  EXPECT_GT(at("head").z(), at("neck").z());
  EXPECT_GT(at("neck").z(), at("pelvis").z());
  EXPECT_GT(at("foot_l").z(), 0.03);
  EXPECT_LT(at("foot_l").z(), 0.15);
  EXPECT_GT(at("toe_l").x(), at("foot_l").x() + 0.05);  // toes point forward (+x)
  EXPECT_GT(at("hand_l").y(), 0.3);                        // left is +y
  EXPECT_LT(at("hand_r").y(), -0.3);
  EXPECT_NEAR(at("pelvis").z() / default_character().height, 0.55, 0.04);
}

TEST(Character, VertexCountNearTarget) {
  const Mesh& mesh = default_character().skin.rest;
  EXPECT_GE(mesh.num_vertices(), 3000u);
  EXPECT_LE(mesh.num_vertices(), 10000u);
  EXPECT_NEAR(static_cast<double>(mesh.num_vertices()), 5000.0, 500.0);
  EXPECT_NO_THROW(mesh.check("rest mesh"));
}

TEST(Character, MeshIsClosedOrientedManifoldSphere) {
  expect_closed_manifold_sphere(default_character().skin.rest);
}

TEST(Character, ExtremeBodiesAreClosedSpheresToo) {
  struct Body {
    double height, build;
  };
  for (const Body body : {Body{1.2, 0.75}, Body{2.2, 1.35}, Body{1.5, 1.35}, Body{2.0, 0.75}}) {
    CharacterOptions options;
    options.height = body.height;
    options.build = body.build;
    options.target_vertices = 3000;
    options.texture_size = 256;
    const Character c = make_procedural_character(options, 5);
    SCOPED_TRACE(testing::Message() << "height " << body.height << " build " << body.build);
    expect_closed_manifold_sphere(c.skin.rest);
    EXPECT_NEAR(c.height, body.height, 1e-5);
    EXPECT_NEAR(static_cast<double>(c.skin.rest.num_vertices()), 3000.0, 300.0);
    EXPECT_FALSE(has_self_intersections(c.skin.rest));
  }
}

TEST(Character, MeshFacesOutwardAndHasHumanVolume) {
  const double volume = signed_volume(default_character().skin.rest);
  // An adult of 1.75 m: about 0.06 - 0.09 m^3.
  EXPECT_GT(volume, 0.05);
  EXPECT_LT(volume, 0.1);
}

TEST(Character, RestMeshDoesNotSelfIntersect) {
  EXPECT_FALSE(has_self_intersections(default_character().skin.rest));
}

TEST(Character, HeightAndFloorContactAsConfigured) {
  for (double height : {1.75, 1.6}) {
    CharacterOptions options;
    options.height = height;
    options.target_vertices = 3500;
    options.texture_size = 256;
    const Character c = height == 1.75 ? default_character() : make_procedural_character(options, 3);
    Vec3f lo, hi;
    bounding_box(c.skin.rest, &lo, &hi);
    EXPECT_NEAR(lo.z(), 0.0, 1e-6);
    EXPECT_NEAR(hi.z(), height, 1e-5);
    EXPECT_NEAR(c.height, height, 1e-5);
    // Facing +x: the toes reach further forward than the heels reach back.
    EXPECT_GT(hi.x(), -lo.x());
    // Arms in an A-pose: wider than deep.
    EXPECT_GT(hi.y() - lo.y(), 2.5 * (hi.x() - lo.x()));
  }
}

TEST(Character, SkinWeightsAreValidAndSumToOne) {
  const SkinnedMesh& skin = default_character().skin;
  const int joints = static_cast<int>(default_character().skeleton.size());
  ASSERT_EQ(skin.weights.size(), skin.rest.num_vertices());
  ASSERT_EQ(skin.joints.size(), skin.rest.num_vertices());
  ASSERT_EQ(skin.inverse_bind.size(), static_cast<std::size_t>(joints));
  std::set<int> used;
  for (std::size_t v = 0; v < skin.weights.size(); ++v) {
    EXPECT_NEAR(skin.weights[v].sum(), 1.0f, 1e-6f);
    for (int k = 0; k < 4; ++k) {
      EXPECT_GE(skin.weights[v][k], 0.0f);
      EXPECT_GE(skin.joints[v][k], 0);
      EXPECT_LT(skin.joints[v][k], joints);
    }
    int largest = 0;
    skin.weights[v].maxCoeff(&largest);
    used.insert(skin.joints[v][largest]);
  }
  // Every joint dominates some part of the body (weighs the most there).
  EXPECT_EQ(used.size(), static_cast<std::size_t>(joints));
}

// Wider, smoother skinning blends more of the skin between bones (the armpit's skin then
// stretches less as the arm rises); the mesh and the skeleton stay the same.
int blended_vertices(const Character& c) {
  int n = 0;
  for (const Eigen::Vector4f& w : c.skin.weights) n += w.maxCoeff() < 0.9f;
  return n;
}

// The performer skinned as narrowly at the trunk as elsewhere (the default is wider there).
const Character& narrow_character() {
  static const Character character = [] {
    CharacterOptions narrow;
    narrow.trunk_skin_blend = narrow.skin_blend;
    return make_procedural_character(narrow, 1);
  }();
  return character;
}

TEST(Character, WiderSkinBlendBlendsMoreOfTheSkin) {
  CharacterOptions wide;
  wide.skin_blend = 3;
  wide.skin_smoothing = 20;
  const Character wide_character = make_procedural_character(wide, 1);
  ASSERT_EQ(wide_character.skin.rest.positions, narrow_character().skin.rest.positions);
  // Narrow, about half the vertices have no weight of 0.9 (the smoothing); wider, more than a
  // fifth of the mesh more.
  const int vertices = static_cast<int>(wide_character.skin.weights.size());
  EXPECT_GT(blended_vertices(wide_character), blended_vertices(narrow_character()) + vertices / 5);
  for (const Eigen::Vector4f& w : wide_character.skin.weights) {
    EXPECT_NEAR(w.sum(), 1.0f, 1e-6f);
  }
}

// A wider blend where the limbs join the trunk leaves the hands and feet as they were.
TEST(Character, WiderTrunkSkinBlendLeavesHandsAndFeetAlone) {
  const Character& narrow = narrow_character();
  const Character& trunk_character = default_character();  // trunk_skin_blend 3
  EXPECT_GT(blended_vertices(trunk_character), blended_vertices(narrow) + 100);
  const Skeleton& sk = narrow.skeleton;
  int far_from_trunk = 0;
  for (std::size_t v = 0; v < narrow.skin.weights.size(); ++v) {
    const int j = narrow.skin.joints[v][0];  // the largest weight's joint
    const std::string& name = sk.names[static_cast<std::size_t>(j)];
    if (name.rfind("hand", 0) != 0 && name.rfind("foot", 0) != 0 && name.rfind("toe", 0) != 0) {
      continue;
    }
    ++far_from_trunk;
    EXPECT_EQ(trunk_character.skin.joints[v][0], j) << "vertex " << v;
    EXPECT_NEAR(trunk_character.skin.weights[v][0], narrow.skin.weights[v][0], 0.02f)
        << "vertex " << v << " (" << name << ")";
  }
  EXPECT_GT(far_from_trunk, 500);
}

TEST(Character, RestPoseSkinningReproducesRestMesh) {
  const Character& c = default_character();
  const Mesh posed = skin_mesh(c.skin, forward_kinematics(c.skeleton, rest_pose(c.skeleton)));
  ASSERT_EQ(posed.num_vertices(), c.skin.rest.num_vertices());
  EXPECT_EQ(posed.triangles, c.skin.rest.triangles);
  EXPECT_EQ(posed.uvs, c.skin.rest.uvs);
  float worst = 0;
  for (std::size_t v = 0; v < posed.num_vertices(); ++v) {
    worst = std::max(worst, (posed.positions[v] - c.skin.rest.positions[v]).norm());
  }
  EXPECT_LT(worst, 1e-5f);
}

TEST(Character, SkinningFollowsTheBones) {
  const Character& c = default_character();
  const Skeleton& sk = c.skeleton;
  Pose pose = rest_pose(sk);
  // Raise the left forearm by 90 degrees about the elbow hinge; shift the whole body.
  const int forearm = sk.find("forearm_l");
  pose.local_rotations[static_cast<std::size_t>(forearm)] = Eigen::AngleAxisd(M_PI / 2, Eigen::Vector3d::UnitX());
  pose.root_position += Eigen::Vector3d(1, 2, 0);
  const auto world = forward_kinematics(sk, pose);
  const Mesh posed = skin_mesh(c.skin, world);
  for (std::size_t v = 0; v < posed.num_vertices(); ++v) {
    const Eigen::Vector4f& w = c.skin.weights[v];
    const Eigen::Vector4i& j = c.skin.joints[v];
    Eigen::Vector3d rest = c.skin.rest.positions[v].cast<double>();
    if (j[0] == forearm && w[0] == 1.0f) {
      // Rigidly carried by the forearm.
      const Eigen::Vector3d expected = world[static_cast<std::size_t>(forearm)] * c.skin.inverse_bind[static_cast<std::size_t>(forearm)] * rest;
      EXPECT_LT((posed.positions[v].cast<double>() - expected).norm(), 1e-5);
    }
    if (j[0] == sk.find("thigh_r") && w[0] == 1.0f) {
      EXPECT_LT((posed.positions[v].cast<double>() - (rest + Eigen::Vector3d(1, 2, 0))).norm(), 1e-5);
    }
  }
}

TEST(Character, UvsAndTextureAreUsable) {
  const Character& c = default_character();
  ASSERT_EQ(c.skin.rest.uvs.size(), c.skin.rest.num_vertices());
  for (const Vec2f& uv : c.skin.rest.uvs) {
    EXPECT_GE(uv.x(), 0.0f);
    EXPECT_LE(uv.x(), 1.0f);
    EXPECT_GE(uv.y(), 0.0f);
    EXPECT_LE(uv.y(), 1.0f);
  }
  // Edges long in texture space only where two charts meet and at the charts' poles: a few
  // percent of the edges.
  std::size_t stretched = 0, edges = 0;
  for (const Tri& t : c.skin.rest.triangles) {
    for (int k = 0; k < 3; ++k) {
      if (t[k] > t[(k + 1) % 3]) continue;  // each edge once
      ++edges;
      if ((c.skin.rest.uvs[t[k]] - c.skin.rest.uvs[t[(k + 1) % 3]]).norm() > 0.1f) ++stretched;
    }
  }
  EXPECT_LT(stretched, edges / 25);
  ASSERT_EQ(c.texture.type(), CV_8UC3);
  EXPECT_EQ(c.texture.rows, 1024);
  EXPECT_EQ(c.texture.cols, 1024);
  // Never green (the backdrop), and with detail: the gradient magnitude is not small.
  std::size_t green = 0;
  for (int y = 0; y < c.texture.rows; ++y) {
    for (int x = 0; x < c.texture.cols; ++x) {
      const cv::Vec3b p = c.texture.at<cv::Vec3b>(y, x);
      if (p[1] > p[0] + 40 && p[1] > p[2] + 40) ++green;
    }
  }
  EXPECT_EQ(green, 0u);
  cv::Mat grey, dx;
  cv::cvtColor(c.texture, grey, cv::COLOR_BGR2GRAY);
  cv::Sobel(grey, dx, CV_32F, 1, 0);
  EXPECT_GT(cv::mean(cv::abs(dx))[0], 8.0);
}

TEST(Character, DeterministicFromOptionsAndSeed) {
  CharacterOptions options;
  options.target_vertices = 3200;
  options.texture_size = 256;
  const Character a = make_procedural_character(options, 7);
  const Character b = make_procedural_character(options, 7);
  const Character c = make_procedural_character(options, 8);
  EXPECT_EQ(a.skin.rest.positions, b.skin.rest.positions);
  EXPECT_EQ(a.skin.rest.triangles, b.skin.rest.triangles);
  EXPECT_EQ(a.skin.rest.uvs, b.skin.rest.uvs);
  EXPECT_EQ(a.skin.weights, b.skin.weights);
  EXPECT_EQ(a.skin.joints, b.skin.joints);
  EXPECT_EQ(cv::norm(a.texture, b.texture, cv::NORM_INF), 0.0);
  // The seed changes the clothes, not the body.
  EXPECT_EQ(a.skin.rest.positions, c.skin.rest.positions);
  EXPECT_GT(cv::norm(a.texture, c.texture, cv::NORM_L1), 0.0);
}

TEST(Character, BuildChangesGirthNotHeight) {
  CharacterOptions slim, heavy;
  slim.build = 0.85;
  heavy.build = 1.25;
  slim.texture_size = heavy.texture_size = 256;
  const Character a = make_procedural_character(slim, 1);
  const Character b = make_procedural_character(heavy, 1);
  EXPECT_NEAR(a.height, b.height, 1e-5);
  EXPECT_GT(signed_volume(b.skin.rest), 1.3 * signed_volume(a.skin.rest));
}

TEST(Character, DebugViews) {
  if (debug_view::debug_dir().empty()) GTEST_SKIP() << "set FOURD_SYNTH_DEBUG_DIR to write views";
  const Character& c = default_character();
  debug_view::write_debug_image("character_rest.png", debug_view::render_views(c.skin.rest, c.texture, 500));
  debug_view::write_debug_image("character_texture.png", c.texture);
  cv::Mat untextured = debug_view::render_views(c.skin.rest, cv::Mat(), 500);
  debug_view::write_debug_image("character_rest_shaded.png", untextured);
}

}  // namespace
}  // namespace fourd::synth
