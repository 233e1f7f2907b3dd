// PLY meshes: ASCII, binary little- and big-endian.
#include "pipeline/core/mesh_io.h"
#include "tests/fuzz/fuzz_input.h"

namespace fourd::fuzz {

FOURD_FUZZ_TARGET(ply) {
  read_ply(write_input("input.ply", input));
}

}  // namespace fourd::fuzz
