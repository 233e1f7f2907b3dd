#include "stages/timewarp/timewarp_io.h"

#include <fmt/format.h>

#include <cmath>
#include <cstdint>
#include <numbers>

#include "pipeline/core/binary_format.h"
#include "pipeline/core/error.h"

namespace fourd::timewarp {

nlohmann::json cycle_json(const Cycle& c) {
  return {{"start_frame", c.start},
          {"end_frame", c.start + c.period},
          {"period_frames", c.period},
          {"closure_rms_mm", 1000 * c.closure_rms},
          {"variation_rms_mm", 1000 * c.variation_rms},
          {"closure_ratio", c.closure_ratio}};
}

nlohmann::json take_segments_json(const std::string& take, int frames, const TakeSegments& s,
                                  const Cycle* used) {
  nlohmann::json j = {{"take", take}, {"frames", frames}, {"period_frames", s.period}};
  j["cycles"] = nlohmann::json::array();
  for (const Cycle& c : s.cycles) j["cycles"].push_back(cycle_json(c));
  j["one_shots"] = nlohmann::json::array();
  for (const FrameRange& r : s.one_shots) {
    j["one_shots"].push_back({{"first_frame", r.first}, {"last_frame", r.last}});
  }
  j["used_cycle"] = used ? cycle_json(*used) : nlohmann::json(nullptr);
  return j;
}

}  // namespace fourd::timewarp
