// fourd-timewarp: registers the takes of each motion class in time, extracts closed cycles and
// separates root motion from body shape.
#include "stages/common/stage.h"
#include "stages/timewarp/timewarp.h"

int main(int argc, char** argv) {
  fourd::StageInfo info{"timewarp",
                        "Time warping: for each motion class of session.yaml, removes root motion "
                        "(ground-plane translation and heading) from the aligned meshes, extracts a "
                        "closed cycle of cyclic takes, registers the takes to the first one by "
                        "dynamic time warping and writes timewarp/<class>.twarp (resampled shapes, "
                        "root curves, timing) and timewarp/<class>.json.",
                        /*takes_frame_range=*/false, /*supports_oracle=*/true,
                        {fourd::options_section<fourd::timewarp::TimewarpOptions>("timewarp")}};
  return fourd::run_stage_main(argc, argv, info, nullptr, fourd::timewarp::run_timewarp);
}
