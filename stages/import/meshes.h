#pragma once
// Per-frame meshes from another reconstruction tool (PLY or OBJ, one file per frame): any
// topology becomes reconstruct/<take>/<frame>.ply (what align reads); a consistent sequence (one
// topology every frame) becomes align/template.ply + align/<take>/<frame>.ply (what timewarp
// and texture read).
#include <Eigen/Geometry>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <vector>

#include "pipeline/core/calibration_formats.h"
#include "pipeline/core/mesh.h"
#include "stages/import/media.h"

namespace fourd::import {

// The scale of meshes: the bounding-box diagonal of a performer is 1-3 m, so a first frame's
// diagonal up to 10 is metres, up to 500 centimetres, beyond that millimetres.
LengthUnit infer_mesh_unit(double diagonal);

struct MeshCheck {
  int frames = 0;
  int open_frames = 0;          // frames with boundary edges (holes)
  int non_manifold_frames = 0;  // edges shared by more than two triangles, or rejected faces
  std::string first_open;       // "walk/000003"
  std::string first_non_manifold;
  nlohmann::json to_json() const;
};

struct MeshImportOptions {
  std::string units;  // "" (inferred) | m | cm | mm
  bool consistent = false;
  // Session world from the meshes' world (the rotation the calibration import applied).
  Eigen::Matrix3d world_rotation = Eigen::Matrix3d::Identity();
  std::optional<Eigen::Vector3d> volume_centre;  // the cameras' common centre, metres
};

struct MeshImportResult {
  LengthUnit unit = LengthUnit::kMetre;
  std::string unit_origin;
  MeshCheck check;
  std::vector<std::string> warnings;
  std::map<std::string, int> frames;  // per take
};

// The meshes of `files` (frame order) selected by `takes` (times resolved), converted to metres
// in the session world and written as <take_dirs[k]>/<frame>.ply, and with `consistent`
// `template_file` (the first selected frame). Throws InputError naming the file of the first
// frame whose topology differs from the first frame's (consistent), a take beyond the last
// file, or an unreadable mesh.
MeshImportResult import_meshes(const std::vector<std::filesystem::path>& files,
                               const std::vector<TakeSpec>& takes, const MeshImportOptions& options,
                               const std::vector<std::filesystem::path>& take_dirs,
                               const std::filesystem::path& template_file);

}  // namespace fourd::import
