// fourd-play control scripts (runtime/player.h).
#include "runtime/player.h"
#include "tests/fuzz/fuzz_input.h"

namespace fourd::fuzz {

FOURD_FUZZ_TARGET(control_script) {
  parse_control_script(input, "fuzz");
}

}  // namespace fourd::fuzz
