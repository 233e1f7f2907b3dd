#include "pipeline/core/binary_format.h"

#include <fmt/format.h>
#include <gtest/gtest.h>
#include <unistd.h>

#include <cstring>
#include <fstream>

#include "pipeline/core/error.h"
#include "pipeline/core/files.h"
#include "pipeline/core/mesh.h"

namespace fourd {
namespace {

constexpr FileMagic kTestMagic("FOURDTST");
constexpr FileMagic kOtherMagic("FOURDTW");

struct Pod {
  std::int32_t a;
  float b;
  double c;
};

class BinaryFormatTest : public ::testing::Test {
 protected:
  void SetUp() override {
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    dir_ = fs::temp_directory_path() /
           fmt::format("fourd_binary_format_{}_{}", ::getpid(), info->name());
    fs::remove_all(dir_);
    fs::create_directories(dir_);
    file_ = dir_ / "data.bin";
  }
  void TearDown() override { fs::remove_all(dir_); }

  // Saves a small file with one of each kind of value.
  void save_sample(std::uint32_t version = 2) {
    BinaryWriter writer;
    writer.write<std::uint32_t>(7);
    writer.write(Pod{-3, 1.5f, 2.25});
    writer.write(Vec3f(1, 2, 3));
    writer.write(Eigen::Matrix4d::Identity().eval());
    writer.write_vector(std::vector<Vec3f>{{1, 0, 0}, {0, 1, 0}});
    writer.write_vector(std::vector<std::int64_t>{});
    writer.write_string("walk_slow");
    Eigen::MatrixXf matrix(2, 3);
    matrix << 1, 2, 3, 4, 5, 6;
    writer.write_matrix(matrix);
    writer.write_matrix(Eigen::VectorXd::LinSpaced(5, 0, 1).eval());
    writer.save(file_, kTestMagic, version);
  }

  std::string bytes() const { return read_file(file_); }
  void overwrite(const std::string& bytes) const {
    std::ofstream(file_, std::ios::binary | std::ios::trunc) << bytes;
  }
  std::string open_error(std::initializer_list<std::uint32_t> versions = {1, 2}) const {
    try {
      BinaryReader::open(file_, kTestMagic, versions);
    } catch (const InputError& e) {
      return e.what();
    }
    ADD_FAILURE() << "no InputError thrown";
    return "";
  }

  fs::path dir_;
  fs::path file_;
};

bool contains(const std::string& text, std::string_view part) {
  return text.find(part) != std::string::npos;
}

TEST_F(BinaryFormatTest, RoundTrip) {
  save_sample();
  BinaryReader reader = BinaryReader::open(file_, kTestMagic, {1, 2});
  EXPECT_EQ(reader.version(), 2u);
  EXPECT_EQ(reader.read<std::uint32_t>(), 7u);
  Pod pod = reader.read<Pod>();
  EXPECT_EQ(pod.a, -3);
  EXPECT_EQ(pod.b, 1.5f);
  EXPECT_EQ(pod.c, 2.25);
  EXPECT_EQ(reader.read<Vec3f>(), Vec3f(1, 2, 3));
  EXPECT_EQ(reader.read<Eigen::Matrix4d>(), Eigen::Matrix4d::Identity());
  EXPECT_EQ(reader.read_vector<Vec3f>(), (std::vector<Vec3f>{{1, 0, 0}, {0, 1, 0}}));
  EXPECT_TRUE(reader.read_vector<std::int64_t>().empty());
  EXPECT_EQ(reader.read_string(), "walk_slow");
  Eigen::MatrixXf matrix = reader.read_matrix<Eigen::MatrixXf>();
  ASSERT_EQ(matrix.rows(), 2);
  ASSERT_EQ(matrix.cols(), 3);
  EXPECT_EQ(matrix(1, 0), 4.f);
  EXPECT_EQ(matrix(0, 2), 3.f);
  Eigen::VectorXd vector = reader.read_matrix<Eigen::VectorXd>();
  ASSERT_EQ(vector.size(), 5);
  EXPECT_EQ(vector[4], 1.0);
  EXPECT_TRUE(reader.at_end());
  EXPECT_NO_THROW(reader.expect_end());
}

TEST_F(BinaryFormatTest, HeaderLayout) {
  save_sample(2);
  const std::string data = bytes();
  ASSERT_GE(data.size(), kBinaryHeaderSize);
  EXPECT_EQ(data.substr(0, 8), std::string("FOURDTST", 8));
  std::uint32_t version, marker;
  std::uint64_t size, checksum;
  std::memcpy(&version, data.data() + 8, 4);
  std::memcpy(&marker, data.data() + 12, 4);
  std::memcpy(&size, data.data() + 16, 8);
  std::memcpy(&checksum, data.data() + 24, 8);
  EXPECT_EQ(version, 2u);
  EXPECT_EQ(marker, 0x01020304u);
  EXPECT_EQ(size, data.size() - kBinaryHeaderSize);
  EXPECT_EQ(checksum, hash_bytes(std::string_view(data).substr(kBinaryHeaderSize)));
  // A short magic is padded with zeros.
  EXPECT_EQ(kOtherMagic.bytes(), std::string_view("FOURDTW\0", 8));
  EXPECT_EQ(kOtherMagic.text(), "FOURDTW");
}

TEST_F(BinaryFormatTest, RefusesWrongMagic) {
  save_sample();
  EXPECT_THROW(BinaryReader::open(file_, kOtherMagic, {1, 2}), InputError);
  std::string message;
  try {
    BinaryReader::open(file_, kOtherMagic, {1, 2});
  } catch (const InputError& e) {
    message = e.what();
  }
  EXPECT_TRUE(contains(message, "data.bin")) << message;
  EXPECT_TRUE(contains(message, "not a FOURDTW file")) << message;
}

TEST_F(BinaryFormatTest, RefusesUnknownVersion) {
  save_sample(3);
  std::string message = open_error({1, 2});
  EXPECT_TRUE(contains(message, "data.bin")) << message;
  EXPECT_TRUE(contains(message, "version 3 is not supported")) << message;
  EXPECT_NO_THROW(BinaryReader::open(file_, kTestMagic, {3}));
}

TEST_F(BinaryFormatTest, RefusesFlippedPayloadBit) {
  save_sample();
  std::string data = bytes();
  data[data.size() / 2 + kBinaryHeaderSize / 2] ^= 0x10;
  overwrite(data);
  std::string message = open_error();
  EXPECT_TRUE(contains(message, "data.bin")) << message;
  EXPECT_TRUE(contains(message, "checksum")) << message;
}

TEST_F(BinaryFormatTest, RefusesTruncatedFile) {
  save_sample();
  const std::string data = bytes();
  for (std::size_t size :
       {data.size() - 1, kBinaryHeaderSize + 3, std::size_t{20}, std::size_t{0}}) {
    overwrite(data.substr(0, size));
    std::string message = open_error();
    EXPECT_TRUE(contains(message, "data.bin")) << message;
    EXPECT_TRUE(contains(message, "truncated")) << message;
  }
  overwrite(data + "x");
  EXPECT_TRUE(contains(open_error(), "unexpected bytes"));
}

TEST_F(BinaryFormatTest, RefusesOtherByteOrder) {
  save_sample();
  std::string data = bytes();
  const std::uint32_t swapped = 0x04030201u;
  std::memcpy(data.data() + 12, &swapped, 4);
  overwrite(data);
  std::string message = open_error();
  EXPECT_TRUE(contains(message, "data.bin")) << message;
  EXPECT_TRUE(contains(message, "endianness")) << message;
}

TEST_F(BinaryFormatTest, ReadsPastTheEndThrowTruncated) {
  BinaryWriter writer;
  writer.write<std::uint16_t>(5);
  writer.save(file_, kTestMagic, 1);
  BinaryReader reader = BinaryReader::open(file_, kTestMagic, {1});
  EXPECT_THROW(reader.read<std::uint32_t>(), InputError);
  EXPECT_FALSE(reader.at_end());
  EXPECT_THROW(reader.expect_end(), InputError);
  EXPECT_EQ(reader.read<std::uint16_t>(), 5u);
  try {
    reader.read<double>();
    ADD_FAILURE() << "no InputError";
  } catch (const InputError& e) {
    EXPECT_TRUE(contains(e.what(), "truncated")) << e.what();
    EXPECT_TRUE(contains(e.what(), "data.bin")) << e.what();
  }
}

TEST_F(BinaryFormatTest, HugeCountsAreRefusedBeforeAllocating) {
  // A valid file (correct checksum) whose array count claims far more than the payload holds.
  BinaryWriter writer;
  writer.write<std::uint64_t>(std::uint64_t{1} << 61);  // count of a read_vector<Vec3f>
  writer.write<float>(1.f);
  writer.write<std::uint64_t>(~std::uint64_t{0});  // count of a string
  writer.save(file_, kTestMagic, 1);
  BinaryReader reader = BinaryReader::open(file_, kTestMagic, {1});
  try {
    reader.read_vector<Vec3f>();
    ADD_FAILURE() << "no InputError";
  } catch (const InputError& e) {
    EXPECT_TRUE(contains(e.what(), "truncated")) << e.what();
  }

  BinaryWriter strings;
  strings.write<std::uint64_t>(~std::uint64_t{0});
  strings.save(file_, kTestMagic, 1);
  BinaryReader string_reader = BinaryReader::open(file_, kTestMagic, {1});
  EXPECT_THROW(string_reader.read_string(), InputError);

  BinaryWriter matrices;
  matrices.write<std::uint64_t>(std::uint64_t{1} << 40);
  matrices.write<std::uint64_t>(std::uint64_t{1} << 40);
  matrices.save(file_, kTestMagic, 1);
  BinaryReader matrix_reader = BinaryReader::open(file_, kTestMagic, {1});
  EXPECT_THROW(matrix_reader.read_matrix<Eigen::MatrixXd>(), InputError);
}

TEST_F(BinaryFormatTest, SaveIsAtomic) {
  save_sample();
  const std::string before = bytes();
  std::vector<std::string> names;
  for (const auto& entry : fs::directory_iterator(dir_)) names.push_back(entry.path().filename());
  EXPECT_EQ(names, std::vector<std::string>{"data.bin"});
  // Saving into a folder that cannot be created fails without touching anything else.
  BinaryWriter writer;
  writer.write<int>(1);
  EXPECT_THROW(writer.save(file_ / "sub" / "x.bin", kTestMagic, 1), IoError);
  EXPECT_EQ(bytes(), before);
}

}  // namespace
}  // namespace fourd
