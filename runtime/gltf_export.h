#pragma once
// glTF 2.0 export of an asset (`fourd-export`): the template mesh and every captured take as an
// animation clip named after the take, plus optionally the baked result of a control script, in
// one binary .glb that Blender and three.js open.
//
// Scheme: morph targets, one per frame. The mesh is the template (the first take's first frame,
// root motion removed); every frame of every clip is one morph target (its POSITION and NORMAL
// displacement from the template), and a clip animates the mesh node's weights with a LINEAR
// sampler whose keys are one-hot: at key k only target k weighs 1, so between two keys the
// shape moves linearly from one frame to the next, which is what the runtime's blend does
// between samples. Root motion is not baked into the shapes: the same node carries the root's
// ground-plane translation and heading (translation and rotation channels), so a viewer shows
// the character walking through the scene and the clip can be retargeted or looped in place.
// Why morph targets rather than one mesh per frame (node visibility animated by scale): the
// triangles are written once and every frame costs only its vertex displacements; it is the
// standard way glTF stores a vertex animation (Blender imports it as shape keys, three.js as
// morph targets) and the file holds exactly the asset's frames. A clip's weights are dense
// (frames x all targets floats), which stays small next to the displacements (a few hundred
// frames in all).
//
// Times: a take's keys are the take's own capture times (MotionSpace::seconds: the time-warped
// samples the asset stores), so each clip replays its take at its captured pace; the script's
// keys are its output frames (1 / fps apart).
//
// Texture: when the template has UVs (Mesh::uvs, per vertex or per corner) and `texture_png`
// holds an image, TEXCOORD_0 (split at UV seams) and a baseColor texture are written.
#include <filesystem>
#include <string>
#include <vector>

#include "pipeline/core/mesh.h"
#include "runtime/asset.h"
#include "runtime/character.h"
#include "runtime/player.h"

namespace fourd {

// One clip: frames of the body in the root frame (root motion removed) and the root's world
// pose per frame.
struct MeshClip {
  std::string name;
  std::vector<float> times;                      // [s] per frame, strictly increasing
  std::vector<std::vector<Vec3f>> positions;     // per frame, #V
  std::vector<std::vector<Vec3f>> normals;       // per frame, #V (any length > 0)
  std::vector<RootTransform> roots;              // per frame

  int num_frames() const { return static_cast<int>(times.size()); }
};

struct MeshAnimation {
  std::string name;                    // scene and mesh name
  Mesh base;                           // positions, normals, triangles (+ optional UVs)
  std::vector<unsigned char> texture_png;  // baseColor image, written when base has UVs
  std::vector<MeshClip> clips;
};

// Every input of every space of the asset as a clip named after its take, in the graph's order.
std::vector<MeshClip> asset_take_clips(const Asset& asset);
// The template: input 0, sample 0 of the first space (root frame), with its normals and, when
// the asset has textures, the atlas's UVs (per triangle corner).
Mesh asset_template(const Asset& asset);
// That frame's texture (the first space's first take at t = 0) as PNG bytes; empty when the
// asset has no textures.
std::vector<unsigned char> asset_template_texture_png(const Asset& asset);

// Plays `script` on the asset (runtime/player.h's run_player; `options.out_dir` empty writes
// nothing) and keeps every frame as a clip named `name`.
MeshClip bake_control_script(const Asset& asset, const ControlScript& script,
                             PlayerOptions options, const std::string& name);

// Writes `animation` as a .glb, atomically. Throws InputError naming the file for an
// inconsistent animation (sizes, times, clip names not unique), IoError when it cannot be
// written.
void write_mesh_animation_glb(const std::filesystem::path& path, const MeshAnimation& animation);

}  // namespace fourd
