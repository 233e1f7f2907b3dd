// fourd-texture: a UV atlas for the template and a texture map per aligned frame.
#include "stages/common/stage.h"
#include "stages/texture/texture.h"

int main(int argc, char** argv) {
  fourd::StageInfo info{"texture",
                        "Texturing: cuts the aligned template into charts of low distortion, "
                        "flattens them (CGAL LSCM or ARAP) and packs them into one atlas; then, for "
                        "every aligned frame of every take, bakes a texture from the studio's "
                        "images (visibility by ray casting, views weighted by angle and "
                        "resolution, seams levelled, unseen texels filled and marked). Writes "
                        "texture/atlas.ply (+ .json, .png), texture/<take>/<frame>.png and "
                        "texture/report.json.",
                        /*takes_frame_range=*/false, /*supports_oracle=*/true,
                        {fourd::options_section<fourd::texture::TextureOptions>("texture")}};
  return fourd::run_stage_main(argc, argv, info, nullptr, fourd::texture::run_texture);
}
