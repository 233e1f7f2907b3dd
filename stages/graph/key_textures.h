#pragma once
// The key textures of the asset (runtime/textures.h): for every motion space, each input take's
// textures at K evenly spaced phases of the space's time t, taken from the texture stage's
// per-frame textures, downsampled and stored as JPEG in the asset.
//
// The frame shown at phase t of input i is where the time warp put that phase: sample position
// t (F - 1) of the take's `sample_frames` in timewarp/<class>.json, rounded to the nearest
// captured frame. Reads texture/atlas.ply (per-corner UVs, the template's triangles) and
// texture/<take>/<frame>.png|exr.
#include <filesystem>
#include <string>

#include "pipeline/core/config.h"
#include "runtime/motion_graph.h"

namespace fourd::graph {

// The options are the members visit() lists, with their help; the others are tuned values,
// not options (docs/graph.md, "Advanced").
struct KeyTextureOptions {
  int keys = 8;
  int size = 512;
  int jpeg_quality = 90;  // JPEG quality of the stored textures

  template <class V>
  void visit(V& v) {
    v("keys", keys, "key textures per input take, at evenly spaced phases (0: none)",
      Range{0, 256});
    v("size", size, "texels per side of the textures in the asset (0: as baked)",
      Range{0, 16384});
  }
};

// Whether `texture_dir` holds a texture stage's output (its atlas.ply).
bool has_textures(const std::filesystem::path& texture_dir);

// The key textures of every space of `graph`. Throws InputError naming the file for an atlas
// whose triangles are not the graph's, a timewarp summary that disagrees with a space (takes,
// sample count), or a missing or unreadable texture.
AssetTextures build_key_textures(const MotionGraph& graph, const std::filesystem::path& texture_dir,
                                 const std::filesystem::path& timewarp_dir,
                                 const KeyTextureOptions& options);

}  // namespace fourd::graph
