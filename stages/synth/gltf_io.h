#pragma once
// glTF 2.0 exchange of a skinned character and its animation clips, so users can validate the
// pipeline on their own characters (import) and look at the synthetic performer in any glTF
// viewer (export).
//
// Axes: glTF is y-up with the asset facing +z; our world is z-up facing +x (kForward). The two
// are related by one fixed rotation that maps glTF +z (front) to our +x, glTF +x (the
// character's left) to our +y and glTF +y (up) to our +z. Every position, normal, joint frame,
// inverse bind matrix and key is converted with it, both ways, so the exported file has no
// extra conversion node and a glTF character facing its front stands facing kForward here.
#include <filesystem>
#include <string>
#include <vector>

#include "pipeline/core/config.h"
#include "stages/synth/character.h"
#include "stages/synth/motion.h"

namespace fourd::synth {

// Writes `path` (binary glTF, .glb) atomically: one skinned mesh (POSITION, NORMAL, TEXCOORD_0,
// JOINTS_0, WEIGHTS_0, the texture embedded as PNG), a skin whose joints are a node hierarchy
// with the skeleton's rest offsets and the character's inverse bind matrices, and one
// animation per clip, named after its take, with a rotation channel per joint and the root
// translation, one key per frame at the clip's fps (LINEAR).
// Throws InputError (naming the file) on an inconsistent character or clip, IoError if the
// file cannot be written.
void write_gltf_character(const std::filesystem::path& path, const Character& character,
                          const std::vector<MotionClip>& clips);

struct GltfImportOptions {
  double fps = 0;  // rate the animations are sampled at [Hz]; 0 = each animation's own key rate

  template <class V>
  void visit(V& v) {
    v("fps", fps, "animation sampling rate [Hz], 0 = the file's key rate", Range{0, 1000});
  }
};

struct ImportedCharacter {
  Character character;
  std::vector<MotionClip> clips;  // one per glTF animation, take = the animation's name
};

// Reads a skinned glTF (.gltf with its buffers, or .glb): the first skin, every mesh bound to
// it (all triangle primitives merged), the base colour texture (several materials are packed
// side by side into one texture; no texture gives a flat texture of the base colour factor),
// and every animation sampled at `options.fps` (LINEAR with slerp, STEP and CUBICSPLINE keys).
//
// Conversion to our conventions: joints in topological order (skin joints with several root
// nodes get their lowest common ancestor node, or an added "root" joint, as the root); the bind
// pose (from the inverse bind matrices) becomes the rest pose, with every joint frame
// axis-aligned with the world; at most 4 weights per vertex (the largest, renormalised).
// Animated joint translations other than the root's and animated scale are not represented by
// our skeleton and are dropped; morph targets are ignored.
//
// Throws IoError if the file cannot be read, InputError naming the file and what is wrong for
// a file that is not glTF, has no skin or no skinned mesh, uses an accessor type or component
// type a field does not allow, or requires an extension that changes how data is stored
// (Draco, meshopt, quantisation: re-export without compression).
ImportedCharacter read_gltf_character(const std::filesystem::path& path,
                                      const GltfImportOptions& options = {});

}  // namespace fourd::synth
