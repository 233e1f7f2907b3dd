// timewarp/<class>.twarp (stages/timewarp/timewarp_io.h). The header's size and checksum are
// restamped so mutations reach the payload reader (fuzz_input.h).
#include "pipeline/exchange/warped_class.h"
#include "tests/fuzz/fuzz_input.h"

namespace fourd::fuzz {

FOURD_FUZZ_TARGET(twarp) {
  const std::string file = restamp_binary_header(input);
  read_warped_class(write_input("input.twarp", file));
}

}  // namespace fourd::fuzz
