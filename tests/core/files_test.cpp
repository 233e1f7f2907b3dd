// File helpers (pipeline/core/files.h): the atomic writers' temp files are recognised and
// cleaned up after a killed run; free disk space is checked with a clear message.
#include "pipeline/core/files.h"

#include <fmt/format.h>
#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <limits>
#include <vector>

#include "pipeline/core/error.h"
#include "pipeline/core/staged_folder.h"

namespace fourd {
namespace {

class FilesTest : public ::testing::Test {
 protected:
  void SetUp() override {
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    dir_ = fs::temp_directory_path() / fmt::format("fourd_files_{}_{}", ::getpid(), info->name());
    fs::remove_all(dir_);
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }
  fs::path dir_;
};

TEST_F(FilesTest, TempFilesOfTheAtomicWritersAreRecognised) {
  for (const char* name : {"000042.ply", "report.json", "locomotion.twarp", "a.b.c.png", "noext"}) {
    const fs::path temp = temp_path_for(dir_ / name);
    EXPECT_TRUE(is_temp_file(temp)) << temp;
    EXPECT_FALSE(is_temp_file(dir_ / name)) << name;
  }
  AtomicFile file(dir_ / "x.bin");
  EXPECT_TRUE(is_temp_file(file.temp_path())) << file.temp_path();
  for (const char* name : {".hidden", ".fourd_stage.json", ".x.tmp-1.ply", ".x.tmp12-.ply",
                           ".x.tmpab-1.ply", "x.tmp12-3.ply", ".x.tmp12-3y"}) {
    EXPECT_FALSE(is_temp_file(dir_ / name)) << name;
  }
}

TEST_F(FilesTest, RemoveTempFilesLeavesEverythingElse) {
  write_file_atomic(dir_ / "keep.ply", "mesh");
  write_file_atomic(dir_ / "sub" / "keep.json", "{}");
  ensure_directory(dir_ / "sub" / "deeper");
  for (const fs::path& p : {temp_path_for(dir_ / "a.ply"), temp_path_for(dir_ / "sub" / "b.json"),
                            temp_path_for(dir_ / "sub" / "deeper" / "c.png")}) {
    write_file_atomic(p, "half a file");
  }
  EXPECT_EQ(remove_temp_files(dir_), 3);
  std::vector<std::string> left;
  for (const auto& e : fs::recursive_directory_iterator(dir_)) {
    if (e.is_regular_file()) left.push_back(e.path().lexically_relative(dir_).generic_string());
  }
  std::sort(left.begin(), left.end());
  EXPECT_EQ(left, (std::vector<std::string>{"keep.ply", "sub/keep.json"}));
  EXPECT_EQ(remove_temp_files(dir_ / "missing"), 0);
}

TEST_F(FilesTest, FreeSpaceCheckSaysWhatNeedsHowMuch) {
  EXPECT_NO_THROW(require_free_space(dir_ / "not" / "yet", 1024, "a small file"));
  try {
    require_free_space(dir_ / "out", std::numeric_limits<std::uintmax_t>::max() / 2,
                       "segment's masks of 96 frames of 8 cameras");
    FAIL() << "more than the disk holds was accepted";
  } catch (const IoError& e) {
    const std::string message = e.what();
    EXPECT_NE(message.find("segment's masks of 96 frames of 8 cameras"), std::string::npos)
        << message;
    EXPECT_NE(message.find((dir_ / "out").string()), std::string::npos) << message;
    EXPECT_NE(message.find("MiB free"), std::string::npos) << message;
  }
}

// A folder is renamed away before it is deleted: what a killed removal left (under the hidden
// name) is cleared by the next call, and the real name is either whole or gone.
TEST_F(FilesTest, RemoveFolderClearsWhatAKilledRemovalLeft) {
  const fs::path capture = dir_ / "capture";
  const fs::path leftover = dir_ / ".capture.removing.tmp";
  write_file_atomic(capture / "take" / "cam00" / "000000.png", "image");
  write_file_atomic(leftover / "take" / "cam03" / "000007.png", "half-removed");
  remove_folder(capture);
  EXPECT_FALSE(fs::exists(capture));
  EXPECT_FALSE(fs::exists(leftover));
  EXPECT_NO_THROW(remove_folder(capture));  // nothing there: nothing to do
  EXPECT_FALSE(fs::exists(leftover));
}

}  // namespace
}  // namespace fourd
