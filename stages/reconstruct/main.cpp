// fourd-reconstruct: one mesh per frame from the silhouettes, images and calibration (visual
// hull refined by multi-view stereo), plus a COLMAP check of the calibration.
#include "stages/common/stage.h"
#include "stages/reconstruct/reconstruct.h"

int main(int argc, char** argv) {
  fourd::StageInfo info{
      "reconstruct",
      "Multi-view reconstruction: visual hull of segment/, refined by hull-guided plane-sweep "
      "stereo and depth-map fusion, remeshed; writes reconstruct/<take>/<frame>.ply, "
      "reconstruct/report.json and (when the whole session is processed) a COLMAP check of the "
      "calibration in reconstruct/calibration_check/. Split into jobs (--take/--frames), each "
      "writes only its frames; the --finish job then writes the report and the check. Lengths "
      "marked (scaled to the subject) are defaults for a 1.75 m subject: unless session.yaml or "
      "a preset sets them, they are scaled to the subject's size (so are the tuned lengths that "
      "are not options), measured on the visual hull of a few frames (reconstruct/subject.json, "
      "reconstruct/options.yaml has the values used); the capture volume defaults to the volume the cameras share. Every frame's "
      "result is checked against its silhouettes: implausible ones are flagged with warnings.",
      /*takes_frame_range=*/true, /*supports_oracle=*/true,
      {fourd::options_section<fourd::reconstruct::ReconstructOptions>("reconstruct")}};
  info.has_finish_job = true;
  fourd::reconstruct::CalibrationCheckRequest check;
  std::string check_frame;
  auto options = [&](CLI::App& app) {
    app.add_flag("--check-calibration", check.only,
                 "only check the calibration with COLMAP (no reconstruction)");
    app.add_flag("--refine-calibration", check.refine,
                 "refine the calibration with COLMAP's bundle adjustment and write "
                 "reconstruct/calibration_check/refined/");
    app.add_option("--check-take", check.take, "take of the frame the calibration check uses");
    app.add_option("--check-frame", check.frame, "frame the calibration check uses");
  };
  return fourd::run_stage_main(argc, argv, info, options,
                               [&](const fourd::Session& session, const fourd::StageArgs& args) {
                                 fourd::reconstruct::run_reconstruct(session, args, check);
                               });
}
