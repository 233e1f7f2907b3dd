// fourd-motionspace: builds a parametric motion space per motion class from the timewarp
// stage's output (hybrid non-linear blending references, root motion, parameter map).
#include "stages/common/stage.h"
#include "stages/motionspace/motionspace.h"

int main(int argc, char** argv) {
  fourd::StageInfo info{"motionspace",
                        "Parametric motion spaces: for each motion class, adds hybrid blending "
                        "references by recursive bisection until the hybrid blend is within "
                        "epsilon of the non-linear blend, learns the map from the high-level "
                        "parameter to blend weights, and writes motionspace/<class>.mspace, "
                        "<class>.json, table1.json and figure4.png (the paper's Table 1 and "
                        "Figure 4 on the pair of takes that differ most in rotation).",
                        /*takes_frame_range=*/false, /*supports_oracle=*/true,
                        {fourd::options_section<fourd::motionspace::MotionspaceOptions>("motionspace")}};
  return fourd::run_stage_main(argc, argv, info, nullptr, fourd::motionspace::run_motionspace);
}
