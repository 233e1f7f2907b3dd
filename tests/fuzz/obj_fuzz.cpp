// OBJ meshes and the .mtl they name (two parts of one input; the seeds name "input.mtl").
#include "pipeline/core/mesh_io.h"
#include "tests/fuzz/fuzz_input.h"

namespace fourd::fuzz {

FOURD_FUZZ_TARGET(obj) {
  const auto parts = split_parts(input, 2);
  write_input("input.mtl", parts[1]);
  read_obj(write_input("input.obj", parts[0]));
}

}  // namespace fourd::fuzz
