// motionspace/<class>.mspace (runtime/motion_space.h). The header's size and checksum are
// restamped so mutations reach the payload reader (fuzz_input.h).
#include "runtime/motion_space.h"
#include "tests/fuzz/fuzz_input.h"

namespace fourd::fuzz {

FOURD_FUZZ_TARGET(mspace) {
  const std::string file = restamp_binary_header(input);
  load_motion_space(write_input("input.mspace", file));
}

}  // namespace fourd::fuzz
