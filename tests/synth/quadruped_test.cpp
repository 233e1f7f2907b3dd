// The procedural quadruped (character.body quadruped) and its gaits: walk, trot, gallop.
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>

#include "pipeline/core/error.h"
#include "pipeline/geometry/repair.h"
#include "stages/synth/character.h"
#include "stages/synth/motion.h"
#include "tests/synth/mesh_checks.h"
#include "tests/synth/motion_specs.h"

namespace fourd::synth {
namespace {

using test::lowest;

constexpr double kHeight = 0.8;  // the animal the issues cite
constexpr double kFps = 25;

CharacterOptions quadruped_options() {
  CharacterOptions options;
  options.body = "quadruped";
  options.height = kHeight;
  options.texture_size = 256;
  return options;
}

const Character& animal() {
  static const Character character = make_procedural_character(quadruped_options(), 1);
  return character;
}

MotionSpec gait(const std::string& kind, double speed, int frames) {
  MotionSpec spec = test::make_spec(kind, frames);
  spec.speed = speed;
  return spec;
}

// The gaits the tests perform: a walk, a slow and a fast trot, a slow and a fast gallop.
std::vector<MotionSpec> gaits(int frames) {
  return {gait("walk", 0.8, frames), gait("trot", 1.5, frames), gait("trot", 2.2, frames),
          gait("gallop", 3.0, frames), gait("gallop", 4.5, frames)};
}

std::vector<Mesh> skin_all(const MotionClip& clip) {
  std::vector<Mesh> meshes;
  for (const Pose& pose : clip.poses) {
    meshes.push_back(skin_mesh(animal().skin, forward_kinematics(animal().skeleton, pose)));
  }
  return meshes;
}

// The vertices carried mostly by a hoof joint, per leg (front left, front right, hind left,
// hind right).
std::array<std::vector<int>, 4> hoof_vertices() {
  const Character& c = animal();
  const char* names[4] = {"front_hoof_l", "front_hoof_r", "hind_hoof_l", "hind_hoof_r"};
  std::array<std::vector<int>, 4> out;
  for (std::size_t leg = 0; leg < 4; ++leg) {
    const int joint = c.skeleton.find(names[leg]);
    for (std::size_t v = 0; v < c.skin.weights.size(); ++v) {
      float w = 0;
      for (int k = 0; k < 4; ++k) w += c.skin.joints[v][k] == joint ? c.skin.weights[v][k] : 0.0f;
      if (w > 0.5f) out[leg].push_back(static_cast<int>(v));
    }
  }
  return out;
}

// A hoof is on the floor when its lowest vertex is at most this much higher than at rest (where
// the lowest vertex of each hoof is within a millimetre of the floor: the mesh's vertices fall
// where they fall on the hoof's round bottom).
constexpr float kContact = 0.0003f;

TEST(Quadruped, MeshIsOneClosedOrientedManifoldSphere) {
  const Mesh& mesh = animal().skin.rest;
  test::expect_closed_manifold_sphere(mesh);
  EXPECT_GT(test::signed_volume(mesh), 0.0);  // outward-facing
  EXPECT_NEAR(static_cast<double>(mesh.num_vertices()), 5000.0, 500.0);
  EXPECT_FALSE(has_self_intersections(mesh));
}

TEST(Quadruped, OtherSizesAndBuildsAreClosedSpheresToo) {
  for (const auto& [height, build] : {std::pair{0.4, 0.75}, std::pair{1.6, 1.35}}) {
    CharacterOptions options = quadruped_options();
    options.height = height;
    options.build = build;
    options.target_vertices = 3000;
    const Character c = make_procedural_character(options, 2);
    SCOPED_TRACE(testing::Message() << "height " << height << " build " << build);
    test::expect_closed_manifold_sphere(c.skin.rest);
    EXPECT_NEAR(c.height, height, 1e-5);
  }
}

// Standing on four hooves, longer than tall, facing +x, the top of its head at the height.
TEST(Quadruped, StandsOnFourHoovesFacingForward) {
  const Character& c = animal();
  EXPECT_EQ(c.skeleton.size(), 24u);
  EXPECT_TRUE(is_quadruped(c.skeleton));
  Vec3f lo, hi;
  bounding_box(c.skin.rest, &lo, &hi);
  EXPECT_NEAR(lo.z(), 0.0, 1e-6);
  EXPECT_NEAR(hi.z(), kHeight, 1e-5);
  EXPECT_NEAR(c.height, kHeight, 1e-5);
  EXPECT_GT(hi.x() - lo.x(), 1.1 * kHeight);   // nose to tail
  EXPECT_LT(hi.y() - lo.y(), 0.45 * kHeight);  // narrow
  // The head is at the front: the highest vertex is ahead of the middle.
  const auto top = std::max_element(c.skin.rest.positions.begin(), c.skin.rest.positions.end(),
                                    [](const Vec3f& a, const Vec3f& b) { return a.z() < b.z(); });
  EXPECT_GT(top->x(), 0.5f * (lo.x() + hi.x()));
  // Every hoof touches the floor, in the four quadrants under the body; nothing else does.
  const auto hooves = hoof_vertices();
  float front_x = 0, hind_x = 0;
  for (std::size_t leg = 0; leg < 4; ++leg) {
    ASSERT_GT(hooves[leg].size(), 10u) << "leg " << leg;
    EXPECT_NEAR(lowest(c.skin.rest, hooves[leg]), 0.0f, 1e-3f) << "leg " << leg;
    const Vec3f& p = c.skin.rest.positions[static_cast<std::size_t>(hooves[leg].front())];
    EXPECT_EQ(p.y() > 0, leg % 2 == 0) << "leg " << leg;  // left legs on +y
    (leg < 2 ? front_x : hind_x) += p.x() / 2;
  }
  EXPECT_GT(front_x - hind_x, 0.4 * kHeight);
  for (std::size_t v = 0; v < c.skin.rest.num_vertices(); ++v) {
    if (c.skin.rest.positions[v].z() > 0.02f) continue;
    bool on_hoof = false;
    for (const auto& hoof : hooves) on_hoof |= std::find(hoof.begin(), hoof.end(), static_cast<int>(v)) != hoof.end();
    EXPECT_TRUE(on_hoof) << "vertex " << v << " near the floor is not on a hoof";
  }
}

TEST(Quadruped, SkinWeightsSumToOne) {
  const SkinnedMesh& skin = animal().skin;
  const int joints = static_cast<int>(animal().skeleton.size());
  ASSERT_EQ(skin.weights.size(), skin.rest.num_vertices());
  std::vector<int> carried(static_cast<std::size_t>(joints), 0);
  for (std::size_t v = 0; v < skin.weights.size(); ++v) {
    EXPECT_NEAR(skin.weights[v].sum(), 1.0f, 1e-6f);
    for (int k = 0; k < 4; ++k) {
      EXPECT_GE(skin.weights[v][k], 0.0f);
      ASSERT_GE(skin.joints[v][k], 0);
      ASSERT_LT(skin.joints[v][k], joints);
    }
    int largest = 0;
    skin.weights[v].maxCoeff(&largest);
    ++carried[static_cast<std::size_t>(skin.joints[v][largest])];
  }
  // Every bone carries some skin (the tail's tip and every hoof included).
  for (int j = 0; j < joints; ++j) EXPECT_GT(carried[static_cast<std::size_t>(j)], 0) << animal().skeleton.names[j];
}

// A coat, never green (the backdrop), addressed by UVs inside the texture.
TEST(Quadruped, CoatIsNotGreenAndUvsAreInside) {
  const Character& c = animal();
  ASSERT_EQ(c.texture.type(), CV_8UC3);
  EXPECT_LT(test::fraction_near_hue(c.texture, 120, 40), 1e-3);
  ASSERT_EQ(c.skin.rest.uvs.size(), c.skin.rest.num_vertices());
  for (const Vec2f& uv : c.skin.rest.uvs) {
    EXPECT_TRUE(uv.x() > 0 && uv.x() < 1 && uv.y() > 0 && uv.y() < 1);
  }
  // Before a blue screen, no blue either (a seed whose coat would otherwise be any colour).
  const Character blue = make_procedural_character(quadruped_options(), 4, Eigen::Vector3d(0.1, 0.27, 0.73));
  EXPECT_LT(test::fraction_near_hue(blue.texture, 225, 30), 1e-3);
}

TEST(Quadruped, SameSeedSameBytesOtherSeedOtherCoat) {
  const Character again = make_procedural_character(quadruped_options(), 1);
  const Character& a = animal();
  ASSERT_EQ(again.skin.rest.num_vertices(), a.skin.rest.num_vertices());
  EXPECT_EQ(std::memcmp(again.skin.rest.positions.data(), a.skin.rest.positions.data(),
                        a.skin.rest.positions.size() * sizeof(Vec3f)), 0);
  EXPECT_EQ(std::memcmp(again.skin.weights.data(), a.skin.weights.data(), a.skin.weights.size() * sizeof(Eigen::Vector4f)), 0);
  EXPECT_EQ(cv::norm(again.texture, a.texture, cv::NORM_INF), 0.0);
  const Character other = make_procedural_character(quadruped_options(), 9);
  EXPECT_GT(cv::norm(other.texture, a.texture, cv::NORM_L1), 0.0);
  for (const MotionSpec& spec : gaits(20)) {
    const MotionClip x = generate_motion(a.skeleton, spec, kFps), y = generate_motion(a.skeleton, spec, kFps);
    for (std::size_t f = 0; f < x.poses.size(); ++f) {
      EXPECT_EQ(x.poses[f].root_position, y.poses[f].root_position);
      for (std::size_t j = 0; j < a.skeleton.size(); ++j) {
        EXPECT_EQ(x.poses[f].local_rotations[j].coeffs(), y.poses[f].local_rotations[j].coeffs());
      }
    }
  }
}

// Sampled once a cycle, every frame is the first carried a stride along the path: the period
// is exactly cycle_frames (not a whole number of frames). Half a cycle on is another pose.
TEST(Quadruped, GaitsArePeriodicWithTheStatedPeriod) {
  for (const MotionSpec& spec : gaits(30)) {
    SCOPED_TRACE(spec.kind + " at " + std::to_string(spec.speed));
    const MotionClip clip = generate_motion(animal().skeleton, spec, kFps);
    const double cycle = clip.cycle_frames;
    ASSERT_GT(cycle, 6.0);
    EXPECT_GT(std::abs(cycle - std::round(cycle)), 1e-3) << "a whole number of frames by chance";
    // The ground truth's phase runs at one cycle per cycle_frames.
    for (std::size_t f = 0; f < clip.phase.size(); ++f) {
      const double expected = static_cast<double>(f) / cycle;
      EXPECT_NEAR(std::remainder(clip.phase[f] - expected, 1.0), 0.0, 1e-9);
    }
    const double stride = spec.speed * cycle / kFps;
    for (const double step : {1.0, 0.5}) {
      MotionSpec sampled = spec;
      sampled.frames = 3;
      const MotionClip once = generate_motion(animal().skeleton, sampled, kFps / (step * cycle));
      const std::vector<Mesh> meshes = skin_all(once);
      double worst = 0;
      for (int f = 1; f < 3; ++f) {
        for (std::size_t v = 0; v < meshes[0].num_vertices(); ++v) {
          const Eigen::Vector3d shift(step * f * stride, 0, 0);
          worst = std::max(worst, (meshes[f].positions[v].cast<double>() - meshes[0].positions[v].cast<double>() - shift).norm());
        }
      }
      if (step == 1.0) {
        EXPECT_LT(worst, 1e-4) << "not periodic with " << cycle << " frames";
      } else {
        EXPECT_GT(worst, 0.03) << "periodic with half of " << cycle << " frames";
      }
    }
  }
}

// A hoof on the floor stays where it landed; no vertex ever goes below the floor. The
// footfalls are each gait's: the walk always has at least two hooves down, the trot moves
// diagonal pairs together, the gallop has a moment with all four in the air.
TEST(Quadruped, HoovesPlantedInStanceNeverBelowTheFloor) {
  const auto hooves = hoof_vertices();
  for (const MotionSpec& base : gaits(0)) {
    MotionSpec spec = base;
    SCOPED_TRACE(spec.kind + " at " + std::to_string(spec.speed));
    // Two cycles at 100 frames per second.
    const double fps = 100;
    const MotionClip probe = generate_motion(animal().skeleton, gait(spec.kind, spec.speed, 2), fps);
    spec.frames = static_cast<int>(std::ceil(2 * probe.cycle_frames)) + 1;
    const std::vector<Mesh> meshes = skin_all(generate_motion(animal().skeleton, spec, fps));
    EXPECT_GT(test::lowest_vertex(meshes), -1e-3f) << "a vertex below the floor";
    const int n = static_cast<int>(meshes.size());
    std::vector<std::array<bool, 4>> down(static_cast<std::size_t>(n));
    for (std::size_t leg = 0; leg < 4; ++leg) {
      int stances = 0;
      const float contact = lowest(animal().skin.rest, hooves[leg]) + kContact;
      for (int f = 0; f < n; ++f) down[static_cast<std::size_t>(f)][leg] = lowest(meshes[f], hooves[leg]) <= contact;
      for (int f = 0; f < n;) {
        if (!down[static_cast<std::size_t>(f)][leg]) {
          ++f;
          continue;
        }
        int end = f;
        while (end < n && down[static_cast<std::size_t>(end)][leg]) ++end;
        // The hoof's vertices on the floor mid-stance stay put: to within a millimetre, as the
        // cannon, which carries a few per cent of their weight, turns over the planted hoof.
        const Mesh& mid = meshes[(f + end - 1) / 2];
        double best = std::numeric_limits<double>::max(), worst = 0;
        for (int v : hooves[leg]) {
          const Vec3f& p = mid.positions[static_cast<std::size_t>(v)];
          if (p.z() > contact) continue;
          double drift = 0;
          for (int g = f; g < end; ++g) {
            drift = std::max(drift, static_cast<double>((meshes[g].positions[static_cast<std::size_t>(v)] - p).head<2>().norm()));
          }
          best = std::min(best, drift);
          worst = std::max(worst, drift);
        }
        EXPECT_LT(best, 1e-3) << "leg " << leg << " slides in the stance of frames " << f << "-" << end - 1;
        EXPECT_LT(worst, 3e-3) << "leg " << leg << " in the stance of frames " << f << "-" << end - 1;
        ++stances;
        f = end;
      }
      EXPECT_GE(stances, 2) << "leg " << leg;
    }
    int fewest = 4, diagonal_apart = 0;
    for (const auto& d : down) {
      fewest = std::min(fewest, static_cast<int>(d[0] + d[1] + d[2] + d[3]));
      diagonal_apart += (d[0] != d[3]) + (d[1] != d[2]);
    }
    if (spec.kind == "walk") {
      EXPECT_GE(fewest, 2);
    }
    if (spec.kind == "trot") {
      EXPECT_LT(diagonal_apart, n / 10);
    }
    if (spec.kind == "gallop") {
      EXPECT_EQ(fewest, 0);
    }
  }
}

// The trunk rises and falls and pitches with the footfalls.
TEST(Quadruped, BodyBobsAndPitches) {
  const Skeleton& sk = animal().skeleton;
  const int pelvis = sk.find("pelvis"), chest = sk.find("chest");
  for (const MotionSpec& spec : gaits(40)) {
    SCOPED_TRACE(spec.kind + " at " + std::to_string(spec.speed));
    const MotionClip clip = generate_motion(sk, spec, kFps);
    double lo = 1e9, hi = -1e9, pitch_lo = 1e9, pitch_hi = -1e9;
    for (const Pose& pose : clip.poses) {
      const auto world = forward_kinematics(sk, pose);
      const Eigen::Vector3d a = world[static_cast<std::size_t>(pelvis)].translation();
      const Eigen::Vector3d b = world[static_cast<std::size_t>(chest)].translation();
      lo = std::min(lo, a.z());
      hi = std::max(hi, a.z());
      const double pitch = std::atan2(b.z() - a.z(), (b - a).head<2>().norm()) * 180 / M_PI;
      pitch_lo = std::min(pitch_lo, pitch);
      pitch_hi = std::max(pitch_hi, pitch);
    }
    EXPECT_GT(hi - lo, 0.004);
    EXPECT_LT(hi - lo, 0.1 * kHeight);
    EXPECT_GT(pitch_hi - pitch_lo, spec.kind == "gallop" ? 2.0 : 0.3);
    EXPECT_LT(pitch_hi - pitch_lo, 25.0);
    // The speed is the spec's.
    for (const auto& [name, value] : clip.parameters) {
      if (name == "speed") {
        EXPECT_NEAR(value, spec.speed, 1e-6);
      }
    }
  }
}

template <class F>
void expect_config_error_naming(const std::string& take, F&& f) {
  try {
    f();
    ADD_FAILURE() << "no ConfigError";
  } catch (const ConfigError& e) {
    EXPECT_NE(std::string(e.what()).find(take), std::string::npos) << e.what();
  }
}

TEST(Quadruped, RefusesTheOtherBodysKinds) {
  for (const std::string kind : {"run", "turn", "jump", "reach", "dance"}) {
    MotionSpec spec = test::make_spec(kind, 40);
    spec.take = "take_" + kind;
    spec.speed = 2;
    spec.jump_height = 0.2;
    expect_config_error_naming(spec.take, [&] { generate_motion(animal().skeleton, spec, kFps); });
  }
  CharacterOptions human;
  human.target_vertices = 1500;
  human.texture_size = 64;
  const Character person = make_procedural_character(human, 1);
  for (const std::string kind : {"trot", "gallop"}) {
    MotionSpec spec = gait(kind, 3, 30);
    spec.take = "human_" + kind;
    expect_config_error_naming(spec.take, [&] { generate_motion(person.skeleton, spec, kFps); });
  }
  // A gallop at a walking pace, a walk at a gallop's.
  MotionSpec slow = gait("gallop", 0.8, 30);
  slow.take = "slow_gallop";
  expect_config_error_naming("slow_gallop", [&] { generate_motion(animal().skeleton, slow, kFps); });
  MotionSpec fast = gait("walk", 2.4, 30);
  fast.take = "fast_walk";
  expect_config_error_naming("fast_walk", [&] { generate_motion(animal().skeleton, fast, kFps); });
  // No skirt on a quadruped, no unknown body, no 0.8 m human.
  CharacterOptions skirt = quadruped_options();
  skirt.garment = "skirt";
  EXPECT_THROW(make_procedural_character(skirt, 1), ConfigError);
  CharacterOptions cat = quadruped_options();
  cat.body = "cat";
  EXPECT_THROW(make_procedural_character(cat, 1), ConfigError);
  CharacterOptions small_human;
  small_human.height = 0.8;
  EXPECT_THROW(make_procedural_character(small_human, 1), ConfigError);
}

}  // namespace
}  // namespace fourd::synth
