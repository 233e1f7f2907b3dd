// The fuzz targets (tests/fuzz/*_fuzz.cpp) run here as ordinary tests, on committed inputs:
//  - every seed of tests/fuzz/corpus/<target>/ is a valid file its reader accepts (so the seeds
//    keep reaching deep into the parsers when formats change: regenerate them with
//    tests/fuzz/make_corpus.py), and so is every older-format file of tests/fuzz/legacy/<target>/
//    (run_fuzz.sh gives those to the fuzzer too, so it reaches the conversion of old files);
//  - every input the fuzzer found a bug with, tests/fuzz/regressions/<target>/, is now refused
//    with a typed error (and, in the sanitizer build, without a sanitizer report); those in
//    regressions/<target>/accepted/ crashed a reader on a file it should take (e.g. an OBJ
//    whose material library has a name the file system refuses) and are now accepted.
#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <string>
#include <vector>

#include "pipeline/core/error.h"
#include "pipeline/core/files.h"
#include "tests/fuzz/fuzz_input.h"

namespace fourd::fuzz {
namespace {

std::vector<fs::path> inputs(const std::string& kind, const std::string& target) {
  const fs::path dir = fs::path(FOURD_SOURCE_DIR) / "tests" / "fuzz" / kind / target;
  std::vector<fs::path> files;
  if (!fs::is_directory(dir)) return files;
  for (const auto& e : fs::directory_iterator(dir)) {
    if (e.is_regular_file()) files.push_back(e.path());
  }
  std::sort(files.begin(), files.end());
  return files;
}

TEST(FuzzTargets, EveryTargetHasSeeds) {
  ASSERT_GE(targets().size(), 10u);
  for (const auto& [name, target] : targets()) {
    EXPECT_FALSE(inputs("corpus", name).empty()) << "no seeds in tests/fuzz/corpus/" << name;
  }
}

TEST(FuzzTargets, EverySeedIsAccepted) {
  for (const auto& [name, target] : targets()) {
    std::vector<fs::path> seeds = inputs("corpus", name);
    for (const fs::path& legacy : inputs("legacy", name)) seeds.push_back(legacy);
    for (const fs::path& seed : seeds) {
      try {
        target(read_file(seed));
      } catch (const Error& e) {
        ADD_FAILURE() << name << ": seed " << seed << " is refused: " << e.what();
      }
    }
  }
}

TEST(FuzzTargets, EveryRegressionInputIsRefusedWithATypedError) {
  int count = 0;
  for (const auto& [name, target] : targets()) {
    for (const fs::path& input : inputs("regressions", name)) {
      SCOPED_TRACE(input.string());
      try {
        target(read_file(input));
        ADD_FAILURE() << name << ": accepted " << input;
      } catch (const Error& e) {
        EXPECT_FALSE(std::string(e.what()).empty());
        ++count;
      }
    }
  }
  RecordProperty("regression_inputs", count);
}

TEST(FuzzTargets, RegressionInputsOfReadableFilesAreAccepted) {
  for (const auto& [name, target] : targets()) {
    for (const fs::path& input : inputs("regressions", name + "/accepted")) {
      SCOPED_TRACE(input.string());
      try {
        target(read_file(input));
      } catch (const Error& e) {
        ADD_FAILURE() << name << ": refused " << input << ": " << e.what();
      }
    }
  }
}

}  // namespace
}  // namespace fourd::fuzz
