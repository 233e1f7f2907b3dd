// BVH motion capture (stages/synth/bvh_io.h), y-up centimetres as most files are.
#include "stages/synth/bvh_io.h"
#include "tests/fuzz/fuzz_input.h"

namespace fourd::fuzz {

FOURD_FUZZ_TARGET(bvh) {
  synth::read_bvh(write_input("input.bvh", input));
}

}  // namespace fourd::fuzz
