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
// holds an image, TEXCOORD_0 (split at UV seams) and a baseColor texture are written (as the
// PNG it is, or re-encoded at another size or as JPEG / WebP: GlbOptions).
//
// Compression (GlbOptions::compress): every vertex stream, index buffer and animation key array
// is compressed with meshoptimizer's codecs (EXT_meshopt_compression, required), and the vertex
// data is quantised (KHR_mesh_quantization, required): the morph targets' position
// displacements as 16-bit integers on a grid of step `position_step_mm` (larger when the largest
// displacement would need more than 32,767 steps), the template's positions as floats in the
// grid's units, both dequantised by the mesh node's translation (the template's bounding-box
// centre) and uniform scale (the step), so a decoded vertex is within step * sqrt(3) / 2 of the
// exact one (half a step per component); normals and normal displacements as normalised 8-bit
// integers (displacements clamped
// to [-1, 1]); UVs as normalised 16-bit integers. The root motion then animates a parent node
// of the mesh node, so the node carrying the dequantisation stays static.
#include <opencv2/core.hpp>

#include <filesystem>
#include <string>
#include <vector>

#include "pipeline/core/mesh.h"
#include "pipeline/gltf/gltf.h"
#include "runtime/asset.h"
#include "runtime/character.h"
#include "runtime/player.h"
#include "runtime/textures.h"

namespace fourd {

// One clip: frames of the body in the root frame (root motion removed) and the root's world
// pose per frame.
struct MeshClip {
  std::string name;
  std::vector<float> times;                      // [s] per frame, strictly increasing
  std::vector<std::vector<Vec3f>> positions;     // per frame, #V
  std::vector<std::vector<Vec3f>> normals;       // per frame, #V (any length > 0)
  std::vector<RootTransform> roots;              // per frame
  std::vector<TextureBlend> textures;            // per frame; empty without textures

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

// How a texture is written: as it is (PNG at its size) or resized and re-encoded.
struct TextureEncoding {
  int size = 0;                // > 0: the longer side is resized to this many pixels
  std::string format = "png";  // png | jpeg | webp (in a .glb: EXT_texture_webp, required)
  int quality = 90;            // jpeg / webp quality, 1..100
  bool keeps_png() const { return size == 0 && format == "png"; }
  std::string extension() const;  // ".png", ".jpg", ".webp"
  std::string mime_type() const;
  // Throws UsageError naming the option.
  void check() const;
};
// `image` (8-bit BGR) resized and encoded as `encoding` says; IoError when it cannot be.
std::vector<unsigned char> encode_texture(const cv::Mat& image, const TextureEncoding& encoding);

struct GlbOptions {
  bool compress = false;   // EXT_meshopt_compression + KHR_mesh_quantization (see above)
  double position_step_mm = 0.8;  // grid step of the displacements [mm], 0.001..10
  TextureEncoding texture;
  // Throws UsageError naming the option.
  void check() const;
};

// The vertices as the .glb stores them (which template vertex and UV each copies, and the
// triangles over them): split at UV seams and, compressed, reordered for the codecs.
gltf::ExportVertices glb_vertices(const Mesh& base, const GlbOptions& options);

// Writes `animation` as a .glb, atomically. Throws InputError naming the file for an
// inconsistent animation (sizes, times, clip names not unique), IoError when it cannot be
// written. With the default options the file is the plain one (float attributes, the PNG as
// given).
void write_mesh_animation_glb(const std::filesystem::path& path, const MeshAnimation& animation,
                              const GlbOptions& options = {});

}  // namespace fourd
