// The libFuzzer entry point of a fuzz executable: feeds each input to the one target linked
// into it (tests/fuzz/<name>_fuzz.cpp). A typed fourd::Error is the clean refusal and is
// swallowed; any other exception escapes, and libFuzzer reports it as a crash.
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <string_view>

#include "pipeline/core/error.h"
#include "pipeline/core/log.h"
#include "tests/fuzz/fuzz_input.h"

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  fourd::log::set_level(fourd::log::Level::kError);  // warnings about bad input are expected
  if (fourd::fuzz::targets().size() != 1) std::abort();
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  static const fourd::fuzz::Target target = fourd::fuzz::targets().begin()->second;
  try {
    target({reinterpret_cast<const char*>(data), size});
  } catch (const fourd::Error&) {
  }
  return 0;
}
