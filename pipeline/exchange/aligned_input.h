#pragma once
// The align stage's output as the later stages read it: align/template.ply and
// align/<take>/NNNNNN.ply, one topology for every frame (or oracle/align/, or a consistent
// mesh sequence brought in by fourd-import).
#include <Eigen/Core>
#include <filesystem>
#include <string>
#include <vector>

#include "pipeline/core/mesh.h"

namespace fourd {

// The template and the frames of one take: align/<take>/000000.ply, 000001.ply, ... (frame
// numbers contiguous from 0). Throws InputError naming the take and frame for a missing
// folder, a gap, a frame with another vertex count or topology than the template, or
// non-finite positions.
struct AlignedInput {
  Mesh template_mesh;
  std::filesystem::path dir;
};
AlignedInput open_aligned_input(const std::filesystem::path& dir);
std::vector<Eigen::Matrix3Xd> load_take(const AlignedInput& input, const std::string& take);

}  // namespace fourd
