// The runtime asset (runtime/asset.h), then a character built on it and stepped through a
// transition: an asset the loader accepts must play without crashing. The header's size and
// checksum are restamped so mutations reach the payload reader (fuzz_input.h).
#include "runtime/asset.h"
#include "runtime/character.h"
#include "tests/fuzz/fuzz_input.h"

namespace fourd::fuzz {

FOURD_FUZZ_TARGET(asset) {
  const std::string file = restamp_binary_header(input);
  const Asset asset = load_asset(write_input("input.fourd", file));
  Character character(asset.graph, asset.transitions);
  const int spaces = static_cast<int>(asset.graph.spaces.size());
  character.reset(0, 0);  // clamped into the space's parameter range
  character.request_motion(spaces - 1, 0);
  for (int i = 0; i < 60; ++i) character.step(1.0 / 30);
}

}  // namespace fourd::fuzz
