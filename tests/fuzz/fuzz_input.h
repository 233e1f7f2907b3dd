#pragma once
// Helpers shared by the libFuzzer targets (tests/fuzz/*_fuzz.cpp, built with -DFOURD_FUZZ=ON).
//
// Every parser under test reads files, so a target writes the fuzzer's bytes to a file in a
// private temporary folder and calls the real reader on it. The reader may throw one of the
// typed errors of pipeline/core/error.h (that is the clean refusal we want); anything else --
// another exception, a crash, a sanitizer report, a leak or a hang -- is a bug the fuzzer
// reports.
#include <filesystem>
#include <map>
#include <string>
#include <string_view>
#include <vector>


namespace fourd::fuzz {

// A folder private to this process, emptied at exit.
const std::filesystem::path& scratch_dir();

// Writes `bytes` to scratch_dir()/name (not atomically: nothing else reads it) and returns
// the path.
std::filesystem::path write_input(const std::string& name, std::string_view bytes);

// Splits a multi-file input at lines "--8<-- NAME": the part before the first marker is
// `parts[0]`, each marker starts the next part. Seeds for the multi-file targets are written
// that way (tests/fuzz/corpus/); missing parts are empty.
std::vector<std::string_view> split_parts(std::string_view text, std::size_t count);

// For the versioned binary formats (pipeline/core/binary_format.h): rewrites the header's
// payload size and checksum to match the bytes after it, so mutations of the payload reach the
// format's own reader instead of stopping at the checksum. Magic, version and byte order are
// left as the fuzzer made them. Inputs shorter than a header are returned unchanged.
std::string restamp_binary_header(std::string_view file);

// A fuzz target: feeds one input to the real reader. A typed fourd::Error is the clean
// refusal; any other exception, a crash or a sanitizer report is a bug.
using Target = void (*)(std::string_view input);

// Every target linked into this program, by name (a fuzz executable holds one; the unit-test
// program holds all of them, to check the seeds and the regression inputs).
const std::map<std::string, Target>& targets();
struct Registration {
  Registration(const char* name, Target target);
};

}  // namespace fourd::fuzz

// Defines and registers target NAME, whose seeds are in tests/fuzz/corpus/NAME/:
//   FOURD_FUZZ_TARGET(ply) { read_ply(write_input("input.ply", input)); }
#define FOURD_FUZZ_TARGET(NAME)                                                   \
  static void fourd_fuzz_##NAME(std::string_view input);                          \
  static const ::fourd::fuzz::Registration fourd_fuzz_registration_##NAME(#NAME,  \
                                                                          &fourd_fuzz_##NAME); \
  static void fourd_fuzz_##NAME(std::string_view input)

namespace fourd::fuzz {

}  // namespace fourd::fuzz
