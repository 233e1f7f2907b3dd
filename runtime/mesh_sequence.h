#pragma once
// Mesh-sequence export (`fourd-export --sequence DIR`): one mesh file per frame of a clip (a
// captured take, or the frames a control script plays) in world coordinates, with the frame's
// texture and a manifest, the kind of folder that mesh-sequence players (Unity's and Blender's
// stop-motion / mesh-cache importers) and MeshLab read.
//
// DIR/frame_NNNNN.ply (or .obj + .mtl): positions (root motion applied: the character walks
// through the scene), normals, the atlas's per-corner UVs and the texture's name;
// DIR/frame_NNNNN.png|jpg|webp: the frame's texture (the asset's key textures blended with the
// frame's weights, as the runtime draws it), when the asset has textures;
// DIR/sequence.json: the clip, its frame rate, the vertex and triangle counts, the axes, the
// overall bounding box and per frame its time, files, bounding box and root.
// The folder is written as a whole (a staging folder renamed onto DIR at the end): a failed run
// leaves DIR as it was.
#include <filesystem>
#include <string>

#include "runtime/asset.h"
#include "runtime/gltf_export.h"

namespace fourd {

struct SequenceOptions {
  std::string format = "ply";  // ply | obj
  TextureEncoding texture;     // the per-frame textures (jpeg is much smaller)
  // Throws UsageError naming the option.
  void check() const;
};

struct SequenceReport {
  int frames = 0;
  double fps = 0;
  std::uintmax_t bytes = 0;  // of the whole folder
};

// Writes `clip` (frames in the root frame, as asset_take_clips and bake_control_script give
// them) of `asset` into `dir`. `fps`: the frame rate written to the manifest (the script's; for
// a take its mean captured rate). Throws InputError for a clip that does not fit the asset,
// IoError when the folder cannot be written.
SequenceReport write_mesh_sequence(const std::filesystem::path& dir, const Asset& asset,
                                   const MeshClip& clip, double fps,
                                   const SequenceOptions& options);

}  // namespace fourd
