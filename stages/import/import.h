#pragma once
// fourd-import: creates or extends a session folder from what a studio has — its calibration in
// a foreign format, one video or image folder per camera, background plates, masks, and meshes
// from another reconstruction tool — in the layout every stage reads:
//
//   calibration/                    COLMAP text model (colmap_model.h), one image per camera
//   capture/<take>/<camera>/<frame>.png
//   plates/<camera>/<index>.png     the empty studio (for plate-difference segmentation)
//   masks/<take>/<camera>/<frame>.png   8-bit 0/255
//   reconstruct/<take>/<frame>.ply  meshes of any topology (what align reads)
//   align/template.ply + align/<take>/<frame>.ply   a consistent sequence (what timewarp reads)
//
// Every folder it writes gets <folder>/imported.json, written last:
//   {"tool": "fourd-import", "what": "calibration|capture|plates|masks|reconstruct|align",
//    "source": [...], "takes": {...}, "checks": {...}}
// (the `fourd` driver counts such a folder as done and never overwrites it). Everything is
// written into staging folders inside the session and renamed into place when every check has
// passed, so a failed import leaves the session as it was.
#include <filesystem>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include "stages/import/calibration_import.h"

namespace fourd::import {

struct ImportOptions {
  std::filesystem::path session;
  std::string name;  // a new session's name (default: the folder's name)
  bool replace = false;  // replace folders/takes that exist (else an error)

  CalibrationSource calibration;  // no paths: use the session's calibration/

  // Frames: videos (files or folders, matched to cameras by name) or an image pattern.
  std::vector<std::filesystem::path> videos;
  std::map<std::string, std::filesystem::path> video_for;  // --video CAMERA=FILE
  std::string images;                                      // e.g. "raw/{camera}/img_{frame:04d}.jpg"
  std::vector<std::string> takes;                          // NAME[=FIRST:LAST | =FROMs:TOs]
  int start = 0, end = -1, step = 1;                       // frames of a take given without range
  std::optional<double> from_time, to_time;                // [s], instead of start/end
  double fps = 0;  // 0: the videos', else the session's, else 25

  // Background plates: per camera an image or a video of the empty studio.
  std::vector<std::filesystem::path> plates;
  std::map<std::string, std::filesystem::path> plate_for;
  int plate_frames = 10;  // frames sampled evenly from a plate video

  std::string masks;       // image pattern like `images`
  int mask_threshold = 0;  // a mask pixel above this is foreground (255)

  std::vector<std::filesystem::path> meshes;  // files or folders of .ply/.obj, frame order
  bool consistent = false;                    // one topology every frame: import as align/
  std::string mesh_units;                     // "" (inferred) | m | cm | mm

  // --export-calibration FORMAT --output PATH: write the session's calibration in a foreign
  // format (export_formats()) instead of importing.
  std::string export_format;
  std::filesystem::path export_path;
  std::string export_units = "m";
};

// Does the import (or the export); logs through log.h. Throws typed errors (error.h).
void run_import(const ImportOptions& options);

}  // namespace fourd::import
