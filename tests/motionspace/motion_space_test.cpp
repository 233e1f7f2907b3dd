// The runtime motion space: evaluation at (t, w) and (t, p), timing and root curves, the file
// format.
#include "runtime/motion_space.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <fstream>

#include "pipeline/core/binary_format.h"
#include "pipeline/core/error.h"
#include "pipeline/core/files.h"
#include "tests/motionspace/test_meshes.h"

namespace fourd {
namespace {

constexpr int kSamples = 5;

// Two inputs: a tube bent a little and a lot; input 1 walks twice as far and takes 1.5 x longer.
MotionSpace small_space() {
  const test::TestMesh tube = test::make_tube(9, 8);
  MotionSpace s;
  s.name = "bends";
  s.takes = {"gentle", "strong"};
  s.character_height = 1.0;
  s.triangles = tube.triangles;
  s.blend = make_blend_space(2, static_cast<int>(tube.positions.cols()), kSamples);
  for (int k = 0; k < 2; ++k) {
    for (int i = 0; i < kSamples; ++i) {
      const double angle = (k == 0 ? 0.1 : 0.6) * (1 + i * 0.2);
      set_frame(&s.blend, k, i, test::to_vec3f(test::bend_tube(tube.positions, angle)));
      const float t = static_cast<float>(i) / (kSamples - 1);
      s.roots.push_back({(k + 1) * t, 0.1f * t, 0.2f * k * t});
      s.seconds.push_back((k == 0 ? 1.0f : 1.5f) * t);
    }
  }
  s.parameter_map.parameter = "length";
  s.parameter_map.unit = "m";
  s.parameter_map.num_inputs = 2;
  s.parameter_map.path = {0, 1};
  s.parameter_map.values = {1, 2};
  s.check();
  return s;
}

TEST(MotionSpace, InputWeightsReplayTheInputs) {
  const MotionSpace s = small_space();
  MotionSample out = make_motion_sample(s);
  for (int k = 0; k < 2; ++k) {
    const std::array<float, 2> w{k == 0 ? 1.f : 0.f, k == 1 ? 1.f : 0.f};
    for (int i = 0; i < kSamples; ++i) {
      evaluate_motion_space_weights(s, static_cast<double>(i) / (kSamples - 1), w, &out);
      const float* expected = s.blend.frame(k, i);
      for (std::size_t j = 0; j < s.blend.frame_stride(); ++j) {
        ASSERT_EQ(out.shape.data[j], expected[j]);
      }
      EXPECT_FLOAT_EQ(out.root.x, s.root(k, i).x);
      EXPECT_FLOAT_EQ(out.root.heading, s.root(k, i).heading);
    }
    EXPECT_NEAR(out.duration, k == 0 ? 1.0 : 1.5, 1e-6);
    EXPECT_NEAR(out.seconds_per_t, k == 0 ? 1.0 : 1.5, 1e-6);
  }
}

TEST(MotionSpace, BlendsRootAndPaceWithTheWeights) {
  const MotionSpace s = small_space();
  const std::array<float, 2> w{0.25f, 0.75f};
  const RootPose r = blended_root(s, 0.6, w);
  EXPECT_NEAR(r.x, 0.25 * 0.6 + 0.75 * 1.2, 1e-6);
  EXPECT_NEAR(r.heading, 0.75 * 0.2 * 0.6, 1e-6);
  EXPECT_NEAR(blended_duration(s, w), 0.25 * 1.0 + 0.75 * 1.5, 1e-6);
}

TEST(MotionSpace, ParameterSelectsWeightsWithoutReallocating) {
  const MotionSpace s = small_space();
  MotionSample out = make_motion_sample(s);
  const float* buffer = out.shape.data.data();
  evaluate_motion_space(s, 0.3, 1.25, &out);
  EXPECT_NEAR(out.weights[1], 0.25f, 1e-6);
  EXPECT_FALSE(out.parameter.clamped);
  evaluate_motion_space(s, 0.9, 7.0, &out);
  EXPECT_TRUE(out.parameter.clamped);
  EXPECT_DOUBLE_EQ(out.parameter.applied, 2.0);
  EXPECT_FLOAT_EQ(out.weights[1], 1.f);
  EXPECT_EQ(out.shape.data.data(), buffer);
}

TEST(MotionSpace, FileRoundTripAndCorruption) {
  MotionSpace s = small_space();
  const int mid = add_reference(&s.blend, std::vector<double>{0.5, 0.5});
  const test::TestMesh tube = test::make_tube(9, 8);
  for (int i = 0; i < kSamples; ++i) {
    set_frame(&s.blend, mid, i, test::to_vec3f(test::bend_tube(tube.positions, 0.4 + 0.1 * i)));
  }
  s.blend.cell_arc_angles = {0.7};
  const std::filesystem::path path =
      std::filesystem::temp_directory_path() /
      ("fourd_motion_space_" + std::to_string(::getpid()) + ".mspace");
  save_motion_space(path, s);
  const MotionSpace r = load_motion_space(path);
  EXPECT_EQ(r.name, s.name);
  EXPECT_EQ(r.takes, s.takes);
  EXPECT_EQ(r.triangles, s.triangles);
  EXPECT_EQ(r.blend.cells, s.blend.cells);
  EXPECT_EQ(r.blend.cell_arc_angles, s.blend.cell_arc_angles);
  EXPECT_EQ(r.blend.reference_weights, s.blend.reference_weights);
  ASSERT_EQ(r.blend.frames.size(), s.blend.frames.size());
  EXPECT_TRUE(std::equal(r.blend.frames.begin(), r.blend.frames.end(), s.blend.frames.begin()));
  EXPECT_TRUE(r.blend.displacements == s.blend.displacements);
  EXPECT_EQ(r.seconds, s.seconds);
  EXPECT_EQ(r.parameter_map.values, s.parameter_map.values);
  // A flipped byte in the payload fails the checksum.
  std::string bytes = read_file(path);
  bytes[bytes.size() / 2] ^= 0x5a;
  write_file_atomic(path, bytes);
  EXPECT_THROW(load_motion_space(path), InputError);
  std::filesystem::remove(path);
}

// A version 2 file (every reference's frames in float) loads with its references converted to
// fp16 displacements: the legacy fuzz seed was written by an older fourd from the same session
// as today's seed.
TEST(MotionSpace, VersionTwoFileLoadsAsDisplacements) {
  const std::filesystem::path fuzz = std::filesystem::path(FOURD_SOURCE_DIR) / "tests/fuzz";
  for (const char* name : {"locomotion", "jump_length"}) {
    const MotionSpace old =
        load_motion_space(fuzz / "legacy/mspace" / (std::string(name) + "_v2.mspace"));
    const MotionSpace today =
        load_motion_space(fuzz / "corpus/mspace" / (std::string(name) + ".mspace"));
    EXPECT_GT(old.blend.num_references(), old.blend.num_inputs) << name;
    EXPECT_EQ(old.blend.reference_weights, today.blend.reference_weights) << name;
    EXPECT_TRUE(old.blend.frames == today.blend.frames) << name;
    EXPECT_TRUE(old.blend.displacements == today.blend.displacements) << name;
  }
}

TEST(MotionSpace, LoaderRefusesUnknownVersions) {
  const std::filesystem::path path =
      std::filesystem::temp_directory_path() /
      ("fourd_motion_space_version_" + std::to_string(::getpid()) + ".mspace");
  BinaryWriter w;
  w.write<std::int32_t>(0);
  w.save(path, FileMagic("FOURDMS"), 4);
  EXPECT_THROW(load_motion_space(path), InputError);
  std::filesystem::remove(path);
}

TEST(MotionSpace, CheckRejectsInconsistentSpaces) {
  MotionSpace s = small_space();
  s.seconds[2] = s.seconds[1];  // time must increase
  EXPECT_THROW(s.check(), InputError);
  s = small_space();
  s.roots.pop_back();
  EXPECT_THROW(s.check(), InputError);
  s = small_space();
  s.parameter_map.values = {2, 2};
  EXPECT_THROW(s.check(), InputError);
}

}  // namespace
}  // namespace fourd
