// The runtime asset file (runtime/asset.h): round trip and refusal of bad files.
#include "runtime/asset.h"

#include <fmt/format.h>
#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <fstream>
#include <utility>

#include "pipeline/core/error.h"
#include "pipeline/core/files.h"
#include "pipeline/core/gzip.h"
#include "runtime/asset_packing.h"
#include "tests/graph/test_graph.h"

namespace fourd {
namespace {

class AssetTest : public ::testing::Test {
 protected:
  void SetUp() override {
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    dir_ = fs::temp_directory_path() / fmt::format("fourd_asset_{}_{}", ::getpid(), info->name());
    fs::remove_all(dir_);
    fs::create_directories(dir_);
    file_ = dir_ / "graph.fourd";
  }
  void TearDown() override { fs::remove_all(dir_); }
  fs::path dir_, file_;
};

TEST_F(AssetTest, RoundTripKeepsEverything) {
  Asset a;
  a.graph = test::make_test_graph(true);
  a.transitions.depth = 9;
  save_asset(file_, a);
  const Asset b = load_asset(file_);
  EXPECT_EQ(b.transitions.depth, 9);
  EXPECT_EQ(b.graph.name, a.graph.name);
  EXPECT_DOUBLE_EQ(b.graph.fps, a.graph.fps);
  ASSERT_EQ(b.graph.spaces.size(), a.graph.spaces.size());
  for (std::size_t k = 0; k < a.graph.spaces.size(); ++k) {
    const GraphSpace& x = a.graph.spaces[k];
    const GraphSpace& y = b.graph.spaces[k];
    EXPECT_EQ(x.name(), y.name());
    EXPECT_EQ(x.cyclic(), y.cyclic());
    EXPECT_TRUE(std::equal(x.motion.blend.frames.begin(), x.motion.blend.frames.end(),
                           y.motion.blend.frames.begin(), y.motion.blend.frames.end()));
    EXPECT_TRUE(x.motion.blend.displacements == y.motion.blend.displacements);
    EXPECT_TRUE(std::equal(x.normals.begin(), x.normals.end(), y.normals.begin(), y.normals.end()));
    EXPECT_TRUE(x.normal_displacements == y.normal_displacements);
    EXPECT_EQ(x.motion.blend.cells, y.motion.blend.cells);
    EXPECT_EQ(x.motion.parameter_map.values, y.motion.parameter_map.values);
    EXPECT_EQ(x.motion.seconds, y.motion.seconds);
  }
  ASSERT_EQ(b.graph.edges.size(), a.graph.edges.size());
  for (std::size_t k = 0; k < a.graph.edges.size(); ++k) {
    EXPECT_EQ(a.graph.edges[k].similarity.values, b.graph.edges[k].similarity.values);
    EXPECT_EQ(a.graph.edges[k].precomputed.size(), b.graph.edges[k].precomputed.size());
    EXPECT_EQ(a.graph.edges[k].self_loop, b.graph.edges[k].self_loop);
  }
}

// The default successor is the asset's statement, not recomputed at load: a one-shot space set
// to hold its last pose (-1) stays so, though the graph's rule would send it on.
TEST_F(AssetTest, KeepsTheDefaultSuccessorItStores) {
  Asset a;
  a.graph = test::make_test_graph();
  const int jump = a.graph.find_space("jump_length"), loco = a.graph.find_space("locomotion");
  ASSERT_EQ(a.graph.default_successor(jump), loco);  // the rule's choice, set by the graph build
  EXPECT_EQ(choose_default_successor(a.graph, jump), loco);
  save_asset(file_, a);
  EXPECT_EQ(load_asset(file_).graph.default_successor(jump), loco);
  a.graph.spaces[jump].default_successor = -1;
  save_asset(file_, a);
  const Asset b = load_asset(file_);
  EXPECT_EQ(b.graph.default_successor(jump), -1);
  EXPECT_EQ(b.graph.default_successor(loco), -1);  // cyclic: it loops
}

// A successor the character could not reach by a transition is refused when the asset is
// written, naming the space.
TEST_F(AssetTest, RefusesADefaultSuccessorWithNoTransition) {
  Asset a;
  a.graph = test::make_test_graph();
  const int jump = a.graph.find_space("jump_length"), loco = a.graph.find_space("locomotion");
  for (const auto& [space, next] : {std::pair{loco, jump}, std::pair{jump, jump},
                                    std::pair{jump, 7}}) {
    Asset bad = a;
    bad.graph.spaces[space].default_successor = next;
    try {
      save_asset(file_, bad);
      ADD_FAILURE() << "saved successor " << next << " of space " << space;
    } catch (const InputError& e) {
      EXPECT_NE(std::string(e.what()).find(bad.graph.spaces[space].name()), std::string::npos)
          << e.what();
    }
  }
  EXPECT_FALSE(fs::exists(file_));
}

TEST_F(AssetTest, RefusesUnknownVersion) {
  Asset a;
  a.graph = test::make_test_graph();
  save_asset(file_, a);
  std::string bytes = read_file(file_);
  const std::uint32_t future = kAssetVersion + 1;
  std::memcpy(bytes.data() + 8, &future, sizeof future);
  write_file_atomic(file_, bytes);
  try {
    load_asset(file_);
    FAIL() << "loaded an asset of an unknown version";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("version"), std::string::npos) << e.what();
  }
}

TEST_F(AssetTest, RefusesTruncatedAndCorruptFiles) {
  Asset a;
  a.graph = test::make_test_graph();
  save_asset(file_, a);
  const std::string bytes = read_file(file_);
  write_file_atomic(file_, bytes.substr(0, bytes.size() / 2));
  EXPECT_THROW(load_asset(file_), InputError);
  std::string flipped = bytes;
  flipped[flipped.size() / 2] ^= 0x55;
  write_file_atomic(file_, flipped);
  EXPECT_THROW(load_asset(file_), InputError);
  write_file_atomic(file_, "not an asset");
  EXPECT_THROW(load_asset(file_), InputError);
  EXPECT_THROW(load_asset(dir_ / "missing.fourd"), IoError);
}

// The web package (runtime/asset_packing.h): gzip around the same container, geometry on grids.
// Every loader reads it; what is not geometry comes back exactly, the geometry within its
// steps, and a truncated or corrupt package is refused with the file's name.
TEST_F(AssetTest, WebPackageLoadsWithinItsSteps) {
  Asset a;
  a.graph = test::make_test_graph(true);
  save_asset(file_, a);
  const fs::path package = dir_ / "graph.web.fourd";
  AssetPacking packing;
  save_web_package(package, a, packing);
  const std::string bytes = read_file(package);
  ASSERT_TRUE(is_gzip(bytes));
  EXPECT_LT(bytes.size(), fs::file_size(file_));
  const Asset b = load_asset(package);
  ASSERT_EQ(b.graph.spaces.size(), a.graph.spaces.size());
  for (std::size_t k = 0; k < a.graph.spaces.size(); ++k) {
    const GraphSpace& x = a.graph.spaces[k];
    const GraphSpace& y = b.graph.spaces[k];
    EXPECT_EQ(x.name(), y.name());
    EXPECT_EQ(x.motion.blend.cells, y.motion.blend.cells);
    EXPECT_EQ(x.motion.roots.size(), y.motion.roots.size());
    EXPECT_EQ(x.motion.seconds, y.motion.seconds);
    ASSERT_EQ(x.motion.blend.frames.size(), y.motion.blend.frames.size());
    ASSERT_EQ(x.motion.blend.displacements.size(), y.motion.blend.displacements.size());
    ASSERT_EQ(x.normals.size(), y.normals.size());
    ASSERT_EQ(x.normal_displacements.size(), y.normal_displacements.size());
    const BlendSpace& bx = x.motion.blend;
    for (std::size_t i = 0; i < bx.frames.size(); ++i) {
      if (i % bx.plane_stride >= static_cast<std::size_t>(bx.num_vertices)) continue;
      ASSERT_LE(std::abs(bx.frames[i] - y.motion.blend.frames[i]), 0.5 * packing.position_step + 1e-6)
          << x.name() << " value " << i;
    }
  }
  for (std::size_t k = 0; k < a.graph.edges.size(); ++k) {
    EXPECT_EQ(a.graph.edges[k].similarity.values, b.graph.edges[k].similarity.values);
  }
  const PackingError error = packing_error(a.graph, b.graph);
  EXPECT_GT(error.position_m, 0);  // lossy: it did quantise
  // Inputs within half a step per coordinate, displaced references within about 2 steps.
  EXPECT_LE(error.position_m, 4 * packing.position_step);
  EXPECT_LE(error.normal_deg, 0.1);
  EXPECT_LE(error.normal_displacement, packing.normal_displacement_step);

  // A coarser grid costs accuracy: the error follows the step.
  AssetPacking coarse;
  coarse.position_step = coarse.displacement_step = 1e-3;
  save_web_package(package, a, coarse);
  const PackingError coarse_error = packing_error(a.graph, load_asset(package).graph);
  EXPECT_GT(coarse_error.position_m, 10 * error.position_m);
  EXPECT_LE(coarse_error.position_m, 4 * coarse.position_step);

  write_file_atomic(package, bytes.substr(0, bytes.size() / 2));
  try {
    load_asset(package);
    FAIL() << "loaded a truncated package";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find(package.string()), std::string::npos) << e.what();
  }
  std::string flipped = bytes;
  flipped[flipped.size() / 2] ^= 0x55;
  write_file_atomic(package, flipped);
  EXPECT_THROW(load_asset(package), InputError);
  AssetPacking bad;
  bad.normal_bits = 20;
  EXPECT_THROW(save_web_package(package, a, bad), ConfigError);
}


// The header's fields after the magic, byte-swapped: what a machine of the other endianness
// would have written.
std::string with_swapped_header(std::string bytes) {
  for (std::size_t field : {8, 12}) std::reverse(bytes.begin() + field, bytes.begin() + field + 4);
  for (std::size_t field : {16, 24}) std::reverse(bytes.begin() + field, bytes.begin() + field + 8);
  return bytes;
}

// Every damaged variant of a good asset is refused with an InputError naming the file, and
// never crashes the loader: every truncation inside the header and a spread of them through
// the payload, every single-bit flip of the header, flips spread through the payload, other
// versions and the other byte order.
TEST_F(AssetTest, EveryDamagedVariantIsRefusedWithAMessageNamingTheFile) {
  Asset a;
  a.graph = test::make_test_graph(true);
  save_asset(file_, a);
  const std::string good = read_file(file_);
  const fs::path bad = dir_ / "damaged.fourd";
  int refused = 0;
  auto expect_refused = [&](const std::string& bytes, const std::string& what,
                            const char* reason) {
    write_file_atomic(bad, bytes);
    try {
      load_asset(bad);
      ADD_FAILURE() << what << ": loaded";
    } catch (const InputError& e) {
      const std::string message = e.what();
      EXPECT_NE(message.find(bad.string()), std::string::npos) << what << ": " << message;
      if (reason) {
        EXPECT_NE(message.find(reason), std::string::npos) << what << ": " << message;
      }
      ++refused;
    }
  };
  for (std::size_t n = 0; n < kBinaryHeaderSize + 16; ++n) {
    expect_refused(good.substr(0, n), fmt::format("truncated to {} bytes", n), "truncated");
  }
  for (std::size_t n = kBinaryHeaderSize; n < good.size(); n += good.size() / 97 + 1) {
    expect_refused(good.substr(0, n), fmt::format("truncated to {} bytes", n), "truncated");
  }
  for (std::size_t bit = 0; bit < 8 * kBinaryHeaderSize; ++bit) {
    std::string bytes = good;
    bytes[bit / 8] = static_cast<char>(bytes[bit / 8] ^ (1 << (bit % 8)));
    expect_refused(bytes, fmt::format("header bit {} flipped", bit), nullptr);
  }
  for (std::size_t at = kBinaryHeaderSize; at < good.size(); at += good.size() / 211 + 1) {
    std::string bytes = good;
    bytes[at] = static_cast<char>(bytes[at] ^ (1 << (at % 8)));
    expect_refused(bytes, fmt::format("payload byte {} flipped", at), "checksum mismatch");
  }
  // Version 2 (no textures) still loads: tests/runtime/textures_test.cpp.
  for (std::uint32_t version : {0u, 1u, kAssetVersion + 1, 0xffffffffu}) {
    std::string bytes = good;
    std::memcpy(bytes.data() + 8, &version, sizeof version);
    expect_refused(bytes, fmt::format("version {}", version), "not supported");
  }
  expect_refused(with_swapped_header(good), "other byte order", "other endianness");
  EXPECT_GT(refused, 600);
}

}  // namespace
}  // namespace fourd
