// fourd-align: every reconstructed frame of every take in one template's topology.
#include "stages/align/align.h"
#include "stages/common/stage.h"

int main(int argc, char** argv) {
  fourd::StageInfo info{
      "align",
      "Non-sequential temporal alignment: shape histograms of every frame, a minimum spanning "
      "tree over their distances, a template remeshed from the tree's most central frame, and "
      "non-rigid registration of the template along the tree (embedded deformation + ARAP). "
      "Writes align/template.ply, align/<take>/<frame>.ply in template topology, tree.json, "
      "report.json (per-frame residuals, excluded frames and why) and options.yaml. For a farm it "
      "runs as jobs: --tree (the tree, the template and the tree's top; plans --branches N "
      "branch jobs of whole subtrees), --branch K for each K, then --finish (re-parenting, "
      "reports); without any of these it runs them all, one after the other.",
      /*takes_frame_range=*/true, /*supports_oracle=*/true,
      {fourd::options_section<fourd::align::AlignOptions>("align")}};
  info.tree_jobs = true;
  return fourd::run_stage_main(argc, argv, info, nullptr,
                               [](const fourd::Session& session, const fourd::StageArgs& args) {
                                 fourd::align::run_align(session, args);
                               });
}
