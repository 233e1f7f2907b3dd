// fourd-segment: foreground silhouettes per camera and frame (chroma key, plates or masks).
#include "stages/common/stage.h"
#include "stages/segment/segment.h"

int main(int argc, char** argv) {
  fourd::StageInfo info{"segment",
                        "Foreground segmentation per camera and frame by one method: chroma (learns "
                        "the backdrop's colour per camera and keys it), plate (differences from "
                        "plates/<camera>/<index>.png of the empty studio, shadows and flicker "
                        "tolerated) or masks (masks/<take>/<camera>/<frame>.png, checked); auto "
                        "picks plate, else masks, else chroma. Cleans up and writes "
                        "segment/<take>/<camera>/<frame>.png (0/255) and segment/report.json "
                        "(method, models, foreground fraction and cross-camera consistency per "
                        "take/camera, warnings naming camera and frame). "
                        "Split into jobs (--take/--frames), each writes only its frames; the "
                        "--finish job then writes the report.",
                        /*takes_frame_range=*/true, /*supports_oracle=*/false,
                        {fourd::options_section<fourd::segment::SegmentOptions>("segment")}};
  info.has_finish_job = true;
  return fourd::run_stage_main(argc, argv, info, nullptr, fourd::segment::run_segment);
}
