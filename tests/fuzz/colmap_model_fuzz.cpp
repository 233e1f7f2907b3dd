// The COLMAP text model of a session's calibration/: cameras.txt, images.txt and rig.json,
// given as three parts of one input (fuzz_input.h, split_parts).
#include "pipeline/core/colmap_model.h"
#include "tests/fuzz/fuzz_input.h"

namespace fourd::fuzz {

FOURD_FUZZ_TARGET(colmap_model) {
  const auto parts = split_parts(input, 3);
  write_input("cameras.txt", parts[0]);
  write_input("images.txt", parts[1]);
  const auto rig = scratch_dir() / "rig.json";
  if (parts[2].empty()) {
    std::filesystem::remove(rig);
  } else {
  write_input("rig.json", parts[2]);
  }
  read_colmap_model(scratch_dir());
}

}  // namespace fourd::fuzz
