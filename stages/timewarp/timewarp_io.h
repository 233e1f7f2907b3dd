#pragma once
// Files of the timewarp stage.
//   <class>.twarp  versioned binary (pipeline/core/binary_format.h, magic "FOURDTW"): the
//                  registered, resampled class (WarpedClass) that the motionspace stage reads.
//   <class>.json   what a person or the validator wants to see: per take its cycle, phase
//                  offset, the class time t of every captured frame, duration and root motion.
#include <filesystem>
#include <nlohmann/json.hpp>

#include "stages/timewarp/timewarp.h"

namespace fourd::timewarp {

void write_warped_class(const std::filesystem::path& path, const WarpedClass& warped);
// Throws IoError / InputError naming the file for a missing, corrupt or inconsistent file.
WarpedClass read_warped_class(const std::filesystem::path& path);

nlohmann::json warped_class_summary(const WarpedClass& warped);

}  // namespace fourd::timewarp
