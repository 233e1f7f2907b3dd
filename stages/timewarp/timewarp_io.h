#pragma once
// Files of the timewarp stage.
//   <class>.twarp  versioned binary (pipeline/core/binary_format.h, magic "FOURDTW"): the
//                  registered, resampled class (WarpedClass) that the motionspace stage reads.
//   report.json    per class and take: the period, every cycle that closes, the one-shot
//                  segments between them, the cycle used (see take_segments_json).
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

// report.json: per take, its period, every cycle that closes (with its closure error) and the
// one-shot segments between them (find_cycles), and the cycle the class uses (cyclic classes).
nlohmann::json cycle_json(const Cycle& cycle);
nlohmann::json take_segments_json(const std::string& take, int frames, const TakeSegments& s,
                                  const Cycle* used);

}  // namespace fourd::timewarp
