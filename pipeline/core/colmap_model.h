#pragma once
// The calibration of a camera rig as a COLMAP text model (calibration/ of a session):
//
//   cameras.txt   CAMERA_ID MODEL WIDTH HEIGHT PARAMS...   (one COLMAP camera per physical camera)
//   images.txt    IMAGE_ID QW QX QY QZ TX TY TZ CAMERA_ID NAME, then a POINTS2D line (empty)
//   points3D.txt  empty: a calibration has no scene points
//   rig.json      the rig in the form of COLMAP's rig_bundle_adjuster --rig_config_path:
//                 [{"ref_camera_id": 1, "cameras": [{"camera_id": 1, "image_prefix": "cam00"}, ...]}]
//
// One COLMAP "image" per physical camera; its NAME is "<camera name>.png" and its pose is the
// camera's camera_from_world (COLMAP's qvec/tvec are world-to-camera too). Camera::name is the
// image NAME without its extension.
#include <filesystem>
#include <string>
#include <vector>

#include "pipeline/core/camera.h"

namespace fourd {

// One image of a COLMAP text model. A model from structure-from-motion holds many images per
// COLMAP camera; the session's calibration holds one per physical camera.
struct ColmapImage {
  long long image_id = 0;
  long long camera_id = 0;
  std::string image_name;  // NAME as images.txt writes it, e.g. "cam00.png" or "cam00/0001.jpg"
  Camera camera;           // named by image_name without its extension
};

// Reads cameras.txt and images.txt of any COLMAP text model (rig.json is not checked), or
// cameras.bin and images.bin of a binary model when there is no cameras.txt; images in
// IMAGE_ID order; the same errors as read_colmap_model (a binary file's name its byte offset).
std::vector<ColmapImage> read_colmap_images(const std::filesystem::path& dir);

// Reads cameras.txt and images.txt (or a binary model's cameras.bin and images.bin, as
// read_colmap_images does), and checks rig.json against them when present. Accepts the
// camera models SIMPLE_PINHOLE, PINHOLE, SIMPLE_RADIAL, RADIAL and OPENCV. Cameras come back
// in IMAGE_ID order. Throws InputError naming the file (and line) for a missing folder or file,
// a malformed line, an unknown camera model, an image that references an unknown camera, a
// duplicate id or a duplicate camera name; IoError when an existing file cannot be read.
std::vector<Camera> read_colmap_model(const std::filesystem::path& dir);

// Writes cameras.txt (OPENCV, or PINHOLE for a camera without distortion), images.txt,
// points3D.txt and rig.json into `dir` (created if needed), each file atomically. Numbers are
// printed in their shortest exact form, so reading the model back gives the same values.
// Camera ids and image ids are 1..N in the order of `cameras`. Throws InputError for an empty
// rig, an empty or duplicate name, a name with whitespace, or invalid intrinsics.
void write_colmap_model(const std::filesystem::path& dir, const std::vector<Camera>& cameras);

}  // namespace fourd
