// fourd-segment: foreground silhouettes per camera and frame from the chroma backdrop.
#include "stages/common/stage.h"
#include "stages/segment/segment.h"

int main(int argc, char** argv) {
  fourd::StageInfo info{"segment",
                        "Foreground segmentation: learns a chroma-key backdrop model per camera, "
                        "keys every frame, cleans up and writes segment/<take>/<camera>/<frame>.png "
                        "(0/255) and segment/report.json (foreground fraction per take/camera). "
                        "Split into jobs (--take/--frames), each writes only its frames; the "
                        "--finish job then writes the report.",
                        /*takes_frame_range=*/true, /*supports_oracle=*/false,
                        {fourd::options_section<fourd::segment::SegmentOptions>("segment")}};
  info.has_finish_job = true;
  return fourd::run_stage_main(argc, argv, info, nullptr, fourd::segment::run_segment);
}
