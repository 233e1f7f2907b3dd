#pragma once
// The texture stage: a UV atlas for the template (atlas.h) and, for every aligned frame of every
// take, a texture map baked from the studio's images (bake.h). Per-frame textures share the
// atlas, so the runtime can blend them with the geometry's weights.
//
// Reads align/ (template.ply + <take>/<frame>.ply, one topology; oracle/align/ in oracle mode),
// capture/ and calibration/. Writes, replacing texture/ (texture_oracle/) as a whole:
//   atlas.ply                 the template with per-corner UVs (MeshLab's texcoord)
//   atlas.json                charts, distortion, packing
//   atlas.png                 picture of the charts
//   <take>/<frame>.png|exr    the frame's texture (OBJ UV convention: v up)
//   <take>/unseen/<frame>.png 255 on texels no camera saw (filled from the surface around)
//   report.json               per frame: unseen texels, cameras used or skipped, seams, time
//   options.yaml              the options used
#include <string>

#include "pipeline/core/config.h"
#include "pipeline/core/session.h"
#include "stages/common/stage.h"
#include "stages/texture/atlas.h"
#include "stages/texture/bake.h"

namespace fourd::texture {

// The options are the members visit() lists, with their help; the others are tuned values,
// not options (docs/texture.md, "Advanced"); internal_lengths() lists the tuned lengths scaled
// to the subject.
struct TextureOptions {
  AtlasOptions atlas;
  BakeOptions bake;
  std::string format = "png";

  // One flat section: stages.texture.{resolution, method, format}.
  template <class V>
  void visit(V& v) {
    atlas.visit(v);
    v("format", format, "texture file format: png (8 bits) or exr (half float)");
  }
  template <class V>
  void internal_lengths(V& v) {
    bake.internal_lengths(v);
  }
  void check() const;
};

void run_texture(const Session& session, const StageArgs& args);

}  // namespace fourd::texture
