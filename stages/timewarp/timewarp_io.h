#pragma once
// Files of the timewarp stage.
//   <class>.twarp  the registered, resampled class (WarpedClass) that the motionspace stage
//                  reads: pipeline/exchange/warped_class.h.
//   report.json    per class and take: the period, every cycle that closes, the one-shot
//                  segments between them, the cycle used (see take_segments_json).
//   <class>.json   what a person or the validator wants to see: per take its cycle, phase
//                  offset, the class time t of every captured frame, duration and root motion.
#include <filesystem>
#include <nlohmann/json.hpp>

#include "stages/timewarp/timewarp.h"

namespace fourd::timewarp {

// report.json: per take, its period, every cycle that closes (with its closure error) and the
// one-shot segments between them (find_cycles), and the cycle the class uses (cyclic classes).
nlohmann::json cycle_json(const Cycle& cycle);
nlohmann::json take_segments_json(const std::string& take, int frames, const TakeSegments& s,
                                  const Cycle* used);

}  // namespace fourd::timewarp
