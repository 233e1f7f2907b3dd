// The timewarp stage on a session of synthetic walker takes: outputs, phase accuracy, root
// motion, and bad input (named clearly, nothing half-written).
#include <gtest/gtest.h>

#include <cmath>
#include <nlohmann/json.hpp>

#include "pipeline/core/error.h"
#include "pipeline/core/files.h"
#include "stages/timewarp/timewarp.h"
#include "stages/timewarp/timewarp_io.h"
#include "tests/timewarp/walker_session.h"

namespace fourd::timewarp {
namespace {

namespace fs = std::filesystem;

using test::oracle_args;

void run(const fs::path& root) {
  const Session session = Session::open(root);
  run_timewarp(session, oracle_args(root));
}

std::string error_of(const fs::path& root) {
  try {
    run(root);
  } catch (const Error& e) {
    return e.what();
  }
  return "";
}

// write_ply refuses non-finite positions: a binary PLY written by hand.
void write_ply_unchecked(const fs::path& path, const Mesh& m) {
  std::string bytes = fmt::format(
      "ply\nformat binary_little_endian 1.0\nelement vertex {}\nproperty float x\n"
      "property float y\nproperty float z\nelement face {}\n"
      "property list uchar int vertex_indices\nend_header\n",
      m.positions.size(), m.triangles.size());
  for (const Vec3f& p : m.positions) bytes.append(reinterpret_cast<const char*>(p.data()), 12);
  for (const Tri& t : m.triangles) {
    bytes.push_back(3);
    bytes.append(reinterpret_cast<const char*>(t.data()), 12);
  }
  write_file_atomic(path, bytes);
}

// Output folders besides the final one (staging leftovers).
int stray_folders(const fs::path& root) {
  int n = 0;
  for (const auto& e : fs::directory_iterator(root)) {
    if (e.path().filename().string().find("staging") != std::string::npos ||
        e.path().filename().string().find("previous") != std::string::npos) {
      ++n;
    }
  }
  return n;
}

TEST(TimewarpStage, RegistersTakesAndSeparatesRootMotion) {
  test::WalkerSession s;
  s.write_standard();
  run(s.root());
  const fs::path out = s.root() / "timewarp_oracle";
  ASSERT_TRUE(fs::exists(out / "locomotion.twarp"));
  ASSERT_TRUE(fs::exists(out / "jump_length.twarp"));
  ASSERT_TRUE(fs::exists(out / "options.yaml"));

  const WarpedClass walk = read_warped_class(out / "locomotion.twarp");
  ASSERT_EQ(walk.takes.size(), 2u);
  EXPECT_TRUE(walk.cyclic);
  EXPECT_EQ(walk.num_samples, 16);  // ceil(15 frames) + 1
  // Speeds from the root curves over one cycle.
  const double speeds[2] = {1.0, 1.6};
  for (int k = 0; k < 2; ++k) {
    const WarpedTake& t = walk.takes[k];
    const RootTransform& end = t.roots.back();
    EXPECT_NEAR(std::hypot(end.x, end.y) / t.seconds.back(), speeds[k], 0.02) << t.name;
    EXPECT_NEAR(end.heading, 0.0, 0.02) << t.name;
  }
  EXPECT_NEAR(walk.takes[0].seconds.back(), 15 / 25.0, 0.01);
  EXPECT_NEAR(walk.takes[1].seconds.back(), 12 / 25.0, 0.01);
  // The cycle closes: the last sample's shape is the first's.
  for (int k = 0; k < 2; ++k) {
    EXPECT_EQ(walk.shape(k, 0), walk.shape(k, walk.num_samples - 1));
  }

  // Corresponding poses share t: t - true phase is one constant (mod 1) for both takes.
  const nlohmann::json js = nlohmann::json::parse(read_file(out / "locomotion.json"));
  double sin_sum = 0, cos_sum = 0;
  std::vector<std::pair<double, double>> diffs;  // (t - phase, cycle frames)
  for (const auto& take : js["takes"]) {
    const test::WalkSpec& spec = s.walks.at(take["take"].get<std::string>());
    const std::vector<double> ft = take["frame_t"];
    ASSERT_EQ(static_cast<int>(ft.size()), spec.frames);
    for (int f = 0; f < spec.frames; ++f) {
      const double d = ft[f] - test::walk_phase(spec, f);
      sin_sum += std::sin(test::kTwoPi * d);
      cos_sum += std::cos(test::kTwoPi * d);
      diffs.push_back({d, spec.cycle_frames});
    }
  }
  const double offset = std::atan2(sin_sum, cos_sum) / test::kTwoPi;
  double error = 0;
  for (const auto& [d, frames] : diffs) {
    double e = std::fmod(d - offset, 1.0);
    e = e - std::round(e);
    error += std::abs(e) * frames;
  }
  EXPECT_LT(error / diffs.size(), 0.2);  // mean [frames]

  const WarpedClass jump = read_warped_class(out / "jump_length.twarp");
  EXPECT_FALSE(jump.cyclic);
  const double lengths[2] = {0.6, 1.2};
  for (int k = 0; k < 2; ++k) {
    const RootTransform& end = jump.takes[k].roots.back();
    EXPECT_NEAR(std::hypot(end.x, end.y), lengths[k], 0.01);
  }
  EXPECT_EQ(stray_folders(s.root()), 0);
}

TEST(TimewarpStage, BadInputIsNamedAndLeavesThePreviousOutput) {
  test::WalkerSession s;
  s.write_standard();
  run(s.root());
  const fs::path twarp = s.root() / "timewarp_oracle" / "locomotion.twarp";
  const std::uint64_t before = hash_file(twarp);

  // A class with a single take.
  s.write_config({"{name: locomotion, takes: [walk_slow], parameter: speed, cyclic: true}"});
  {
    const std::string e = error_of(s.root());
    EXPECT_NE(e.find("locomotion has a single take"), std::string::npos) << e;
  }
  s.write_standard();

  // A frame with another vertex count.
  {
    Mesh m = read_ply(s.align_dir() / "walk_fast" / "000003.ply");
    m.positions.pop_back();
    m.triangles.clear();
    write_ply(s.align_dir() / "walk_fast" / "000003.ply", m);
    const std::string e = error_of(s.root());
    EXPECT_NE(e.find("take walk_fast frame 000003"), std::string::npos) << e;
    EXPECT_NE(e.find("vertices"), std::string::npos) << e;
  }
  s.write_standard();

  // Another topology.
  {
    Mesh m = read_ply(s.align_dir() / "jump_long" / "000005.ply");
    std::swap(m.triangles[0], m.triangles[1]);
    write_ply(s.align_dir() / "jump_long" / "000005.ply", m);
    const std::string e = error_of(s.root());
    EXPECT_NE(e.find("take jump_long frame 000005"), std::string::npos) << e;
    EXPECT_NE(e.find("topology"), std::string::npos) << e;
  }
  s.write_standard();

  // NaN in a mesh.
  {
    Mesh m = read_ply(s.align_dir() / "walk_slow" / "000007.ply");
    m.positions[11].y() = std::nanf("");
    write_ply_unchecked(s.align_dir() / "walk_slow" / "000007.ply", m);
    const std::string e = error_of(s.root());
    EXPECT_NE(e.find("take walk_slow frame 000007"), std::string::npos) << e;
  }
  s.write_standard();

  // A cycle that cannot be closed: the fast walk cut to half a cycle.
  {
    fs::remove_all(s.align_dir() / "walk_fast");
    test::WalkSpec half = s.walks.at("walk_fast");
    half.frames = 6;
    s.write_take("walk_fast", test::walk_frames(s.walker(), half));
    const std::string e = error_of(s.root());
    EXPECT_NE(e.find("walk_fast"), std::string::npos) << e;
  }
  // Nothing was half-written: the first run's output is intact, and no staging folder is left.
  EXPECT_EQ(hash_file(twarp), before);
  EXPECT_EQ(stray_folders(s.root()), 0);
}

}  // namespace
}  // namespace fourd::timewarp
