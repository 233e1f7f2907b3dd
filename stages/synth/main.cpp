// fourd-synth: the synthetic studio. Renders the performer of stages.synth in session.yaml
// from the virtual rig and writes capture/, calibration/ and ground_truth/.
#include "stages/common/stage.h"
#include "stages/synth/synth.h"

int main(int argc, char** argv) {
  fourd::StageInfo info{"synth",
                        "Synthetic studio: renders a procedural performer with known geometry, "
                        "motion parameters and calibration from a virtual camera rig; writes "
                        "capture/, calibration/ and ground_truth/ (deterministic from the seed).",
                        false, false, {fourd::options_section<fourd::synth::SynthOptions>("synth")}};
  return fourd::run_stage_main(argc, argv, info, nullptr, fourd::synth::run_synth);
}
