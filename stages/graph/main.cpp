// fourd-graph: builds the 4D parametric motion graph (similarity matrices, precomputed baseline
// transitions) from the motion spaces and writes the runtime asset.
#include "stages/common/stage.h"
#include "stages/graph/graph.h"

int main(int argc, char** argv) {
  fourd::StageInfo info{"graph",
                        "Motion graph: reads the motion space of every class of session.yaml, "
                        "computes the shape-and-velocity similarity matrices of every transition "
                        "session.yaml allows (and of each cyclic space's loop), precomputes the "
                        "n best transitions per edge for the baseline, and writes "
                        "asset/motion_graph.fourd (everything the runtime needs) and "
                        "graph/graph.json.",
                        /*takes_frame_range=*/false, /*supports_oracle=*/true,
                        {fourd::options_section<fourd::graph::GraphOptions>("graph")}};
  return fourd::run_stage_main(argc, argv, info, nullptr, fourd::graph::run_graph);
}
