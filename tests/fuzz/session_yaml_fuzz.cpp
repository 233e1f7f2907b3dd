// session.yaml (pipeline/core/session.h, config.h): YAML mapped onto the options structs.
#include "pipeline/core/session.h"
#include "tests/fuzz/fuzz_input.h"

namespace fourd::fuzz {

FOURD_FUZZ_TARGET(session_yaml) {
  write_input("session.yaml", input);
  Session::open(scratch_dir());
}

}  // namespace fourd::fuzz
