#pragma once
// The raw frames of a session: capture/<take>/<camera>/<frame 000000>.png (see
// Session::capture_image). Every calibrated camera records every frame of every take.
#include <filesystem>
#include <opencv2/core.hpp>
#include <string>
#include <vector>

#include "pipeline/core/camera.h"
#include "pipeline/core/session.h"

namespace fourd {

struct TakeCapture {
  std::string name;       // folder name under capture/, e.g. "walk_slow"
  int frame_count = 0;    // frames 0 .. frame_count-1, the same for every calibrated camera
  // Folders of the take that name no calibrated camera: they are ignored, and a stage may warn.
  std::vector<std::string> uncalibrated_folders;
};

struct CaptureIndex {
  std::vector<TakeCapture> takes;  // sorted by name

  // The take called `name`; throws InputError naming it and the takes that exist.
  const TakeCapture& take(const std::string& name) const;
};

// Lists the takes under capture/ and checks that each calibrated camera has a folder in every
// take with frames 000000.png, 000001.png, ... without gaps, and the same number of frames as
// the other cameras. Hidden files and files not named like frames are ignored. Throws
// InputError naming the take, the camera and (for a gap) the missing frame file.
CaptureIndex scan_capture(const Session& session, const std::vector<Camera>& calibration);

// Decodes capture/<take>/<camera>/<frame>.png as 8-bit BGR. Throws InputError naming the file,
// camera and frame when it is missing, cannot be decoded, or its size differs from the
// camera's calibration; IoError when it exists but cannot be read.
cv::Mat read_capture_image(const Session& session, const Camera& camera, const std::string& take,
                           int frame);

}  // namespace fourd
