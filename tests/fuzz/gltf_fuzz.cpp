// glTF 2.0 characters (stages/synth/gltf_io.h): binary .glb when the input starts with the
// glb magic, else a .gltf JSON (whose external buffers, if any, are missing: a clean error).
#include "stages/synth/gltf_io.h"
#include "tests/fuzz/fuzz_input.h"

namespace fourd::fuzz {

FOURD_FUZZ_TARGET(gltf) {
  const bool glb = input.substr(0, 4) == "glTF";
  synth::read_gltf_character(write_input(glb ? "input.glb" : "input.gltf", input));
}

}  // namespace fourd::fuzz
