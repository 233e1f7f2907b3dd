// The textured runtime (runtime/textures.h): key-texture weights, the CPU blend, the asset's
// texture section (version 3) and older assets without it.
#include "runtime/textures.h"

#include <fmt/format.h>
#include <gtest/gtest.h>
#include <unistd.h>

#include <cstring>

#include "pipeline/core/error.h"
#include "pipeline/core/files.h"
#include "runtime/asset.h"
#include "runtime/character.h"
#include "tests/graph/test_graph.h"

namespace fourd {
namespace {

const MotionGraph& textured_graph() { return test::textured_test_graph(); }

double weight_sum(const TextureBlend& b) {
  double sum = 0;
  for (int k = 0; k < b.count; ++k) sum += b.weights[k];
  return sum;
}

// Largest difference of two 8-bit images, in levels.
int max_difference(const cv::Mat& a, const cv::Mat& b) {
  cv::Mat d;
  cv::absdiff(a, b, d);
  double hi = 0;
  cv::minMaxLoc(d.reshape(1), nullptr, &hi);
  return static_cast<int>(hi);
}

TEST(RuntimeTextures, WeightsSumToOneOverTimesAndWeights) {
  const MotionGraph& g = textured_graph();
  for (int s = 0; s < static_cast<int>(g.spaces.size()); ++s) {
    for (double t = 0; t <= 1.0; t += 0.037) {
      for (float w0 : {0.f, 0.25f, 0.5f, 1.f, -0.3f}) {
        const std::array<float, 2> w{w0, 1 - w0};
        TextureBlend b;
        texture_blend_add(g.textures, s, g.spaces[s].cyclic(), t, w, 1.f, &b);
        EXPECT_NEAR(weight_sum(b), 1.0, 1e-5) << "space " << s << " t " << t << " w0 " << w0;
        EXPECT_LE(b.count, 4);
        for (int k = 0; k < b.count; ++k) {
          EXPECT_GT(b.weights[k], 0.f);
          const SpaceTextures& st = g.textures.spaces[s];
          EXPECT_GE(b.images[k], st.first);
          EXPECT_LT(b.images[k], st.first + st.keys * g.spaces[s].num_inputs());
        }
      }
    }
  }
}

TEST(RuntimeTextures, AKeyPhaseOfOneTakeReproducesItsKeyTexture) {
  const MotionGraph& g = textured_graph();
  cv::Mat out;
  for (int s = 0; s < static_cast<int>(g.spaces.size()); ++s) {
    const SpaceTextures& st = g.textures.spaces[s];
    const bool cyclic = g.spaces[s].cyclic();
    for (int i = 0; i < g.spaces[s].num_inputs(); ++i) {
      for (int k = 0; k < st.keys; ++k) {
        const double t = cyclic ? static_cast<double>(k) / st.keys
                                : static_cast<double>(k) / (st.keys - 1);
        std::array<float, 2> w{0, 0};
        w[i] = 1;
        TextureBlend b;
        texture_blend_add(g.textures, s, cyclic, t, w, 1.f, &b);
        ASSERT_EQ(b.count, 1) << "space " << s << " input " << i << " key " << k;
        EXPECT_EQ(b.images[0], st.first + i * st.keys + k);
        blend_texture_image(g.textures, b, &out);
        EXPECT_EQ(max_difference(out, g.textures.images[st.first + i * st.keys + k]), 0);
      }
    }
  }
  // A cycle's end is its start: t = 1 shows key 0.
  const int loco = g.find_space("locomotion");
  TextureBlend b;
  const std::array<float, 2> w{1, 0};
  texture_blend_add(g.textures, loco, true, 1.0, w, 1.f, &b);
  ASSERT_EQ(b.count, 1);
  EXPECT_EQ(b.images[0], g.textures.spaces[loco].first);
}

TEST(RuntimeTextures, BlendIsTheWeightedMeanOfItsImages) {
  const MotionGraph& g = textured_graph();
  TextureBlend b;
  const std::array<float, 2> w{0.3f, 0.7f};
  texture_blend_add(g.textures, 0, true, 0.4, w, 1.f, &b);  // between keys 1 and 2
  ASSERT_EQ(b.count, 4);
  cv::Mat out;
  blend_texture_image(g.textures, b, &out);
  cv::Mat want(out.size(), CV_32FC3, cv::Scalar::all(0));
  for (int k = 0; k < b.count; ++k) {
    cv::Mat f;
    g.textures.images[b.images[k]].convertTo(f, CV_32FC3);
    want += b.weights[k] * f;
  }
  cv::Mat want8;
  want.convertTo(want8, CV_8UC3);
  EXPECT_LE(max_difference(out, want8), 1);
  EXPECT_GT(max_difference(out, g.textures.images[b.images[0]]), 10);  // really a mix
}

TEST(RuntimeTextures, CharacterFrameCarriesTheBlendThroughTransitionsAndCrossFades) {
  const MotionGraph& g = textured_graph();
  Character c(g, TransitionOptions{});
  const int loco = g.find_space("locomotion"), jump = g.find_space("jump_length");
  c.reset(loco, 1.0, 0.25);  // parameter of input 0, at key 1 of 4
  const TextureBlend& at_key = c.frame().textures;
  ASSERT_EQ(at_key.count, 1);
  EXPECT_EQ(at_key.images[0], g.textures.spaces[loco].first + 1);
  bool faded = false;
  for (int k = 0; k < 400; ++k) {
    if (k == 30) c.request_motion(jump, 0.9);
    const CharacterFrame& f = c.step(1 / 50.0);
    EXPECT_NEAR(weight_sum(f.textures), 1.0, 1e-5) << "frame " << k;
    // The current space's images weigh what its shape does; during a cross-fade the fading
    // space's images take the rest.
    const SpaceTextures& current = g.textures.spaces[c.state().space];
    const int end = current.first + current.keys * g.spaces[c.state().space].num_inputs();
    double own = 0;
    for (int i = 0; i < f.textures.count; ++i) {
      const int im = f.textures.images[i];
      if (im >= current.first && im < end) own += f.textures.weights[i];
    }
    EXPECT_NEAR(own, f.fade_weight, 1e-5) << "frame " << k;
    faded |= f.fade_weight > 0 && f.fade_weight < 1;
  }
  EXPECT_TRUE(faded);
}

class TexturedAssetTest : public ::testing::Test {
 protected:
  void SetUp() override {
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    dir_ = fs::temp_directory_path() / fmt::format("fourd_tex_{}_{}", ::getpid(), info->name());
    fs::remove_all(dir_);
    fs::create_directories(dir_);
    file_ = dir_ / "graph.fourd";
  }
  void TearDown() override { fs::remove_all(dir_); }
  fs::path dir_, file_;
};

// The header's payload size and checksum recomputed, so an edited payload reaches the reader.
std::string restamped(std::string bytes) {
  const std::uint64_t size = bytes.size() - kBinaryHeaderSize;
  const std::uint64_t checksum = hash_bytes(std::string_view(bytes).substr(kBinaryHeaderSize));
  std::memcpy(bytes.data() + 16, &size, sizeof size);
  std::memcpy(bytes.data() + 24, &checksum, sizeof checksum);
  return bytes;
}

TEST_F(TexturedAssetTest, RoundTripKeepsUvsAndTexturesWithinJpegError) {
  Asset a;
  a.graph = textured_graph();
  save_asset(file_, a);
  const Asset b = load_asset(file_);
  const AssetTextures& x = a.graph.textures;
  const AssetTextures& y = b.graph.textures;
  ASSERT_FALSE(y.empty());
  EXPECT_EQ(y.width, x.width);
  EXPECT_EQ(y.height, x.height);
  EXPECT_EQ(y.corner_uvs, x.corner_uvs);
  ASSERT_EQ(y.spaces.size(), x.spaces.size());
  for (std::size_t s = 0; s < x.spaces.size(); ++s) {
    EXPECT_EQ(y.spaces[s].keys, x.spaces[s].keys);
    EXPECT_EQ(y.spaces[s].first, x.spaces[s].first);
  }
  ASSERT_EQ(y.images.size(), x.images.size());
  for (std::size_t k = 0; k < x.images.size(); ++k) {
    cv::Mat d;
    cv::absdiff(x.images[k], y.images[k], d);
    EXPECT_LT(cv::mean(d.reshape(1))[0], 2.0) << "image " << k;  // JPEG at quality 90
  }
}

// A version 2 asset (no texture section, every reference's frames and normals in float) still
// loads, without textures, its references converted to fp16 displacements, and plays. The
// legacy file was written by an older fourd from the same graph as today's fuzz seed.
TEST_F(TexturedAssetTest, VersionTwoAssetLoadsWithoutTextures) {
  const fs::path fuzz = fs::path(FOURD_SOURCE_DIR) / "tests/fuzz";
  const Asset b = load_asset(fuzz / "legacy/asset/tube_graph_no_turns_v2.fourd");
  EXPECT_TRUE(b.graph.textures.empty());
  Character c(b.graph, b.transitions);
  c.reset(0, 1.2);
  EXPECT_EQ(c.step(0.1).textures.count, 0);
  const Asset today = load_asset(fuzz / "corpus/asset/tube_graph_no_turns.fourd");
  ASSERT_EQ(b.graph.spaces.size(), today.graph.spaces.size());
  bool any_reference = false;
  for (std::size_t k = 0; k < b.graph.spaces.size(); ++k) {
    const GraphSpace& x = b.graph.spaces[k];
    const GraphSpace& y = today.graph.spaces[k];
    any_reference |= !x.motion.blend.displacements.empty();
    EXPECT_TRUE(x.motion.blend.frames == y.motion.blend.frames) << x.name();
    EXPECT_TRUE(x.motion.blend.displacements == y.motion.blend.displacements) << x.name();
    EXPECT_TRUE(x.normals == y.normals) << x.name();
    // Today's reference normals are those of the fp16-rounded reference meshes.
    ASSERT_EQ(x.normal_displacements.size(), y.normal_displacements.size());
    for (std::size_t i = 0; i < x.normal_displacements.size(); ++i) {
      ASSERT_NEAR(half_to_float(x.normal_displacements[i]),
                  half_to_float(y.normal_displacements[i]), 2e-3)
          << x.name() << " " << i;
    }
  }
  EXPECT_TRUE(any_reference);
}

// A version 4 asset (before the default successors were stored) loads with the successors the
// graph's rule gives, which are those today's writer stores for the same graph.
TEST_F(TexturedAssetTest, VersionFourAssetGetsTheRulesDefaultSuccessors) {
  const fs::path fuzz = fs::path(FOURD_SOURCE_DIR) / "tests/fuzz";
  const Asset b = load_asset(fuzz / "legacy/asset/tube_graph_no_turns_v4.fourd");
  const Asset today = load_asset(fuzz / "corpus/asset/tube_graph_no_turns.fourd");
  ASSERT_EQ(b.graph.spaces.size(), today.graph.spaces.size());
  bool any_one_shot = false;
  for (int k = 0; k < static_cast<int>(b.graph.spaces.size()); ++k) {
    any_one_shot |= !b.graph.spaces[k].cyclic();
    EXPECT_EQ(b.graph.default_successor(k), choose_default_successor(b.graph, k));
    EXPECT_EQ(b.graph.default_successor(k), today.graph.default_successor(k));
    if (!b.graph.spaces[k].cyclic()) {
      EXPECT_GE(b.graph.default_successor(k), 0);
    }
  }
  EXPECT_TRUE(any_one_shot);
}

TEST_F(TexturedAssetTest, CorruptTexturePayloadIsRefusedNamingTheTexture) {
  Asset a;
  a.graph = textured_graph();
  save_asset(file_, a);
  const std::string good = read_file(file_);
  // The first JPEG: its start-of-image marker FF D8 FF.
  const std::size_t jpeg = good.find("\xFF\xD8\xFF", kBinaryHeaderSize);
  ASSERT_NE(jpeg, std::string::npos);
  std::string bad = good;
  bad[jpeg] = 'X';
  bad[jpeg + 1] = 'Y';
  write_file_atomic(file_, restamped(bad));
  try {
    load_asset(file_);
    FAIL() << "loaded an asset whose key texture does not decode";
  } catch (const InputError& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find(file_.string()), std::string::npos) << what;
    EXPECT_NE(what.find("key texture 0"), std::string::npos) << what;
  }
  // A key texture count that disagrees with the spaces' inputs and keys.
  Asset c;
  c.graph = textured_graph();
  c.graph.textures.images.pop_back();
  EXPECT_THROW(save_asset(file_, c), InputError);
}

}  // namespace
}  // namespace fourd
