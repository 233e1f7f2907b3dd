// Re-imports an exported .glb with tinygltf and compares it with its asset: the mesh has the
// template's vertex count (more only when UV seams split vertices), one morph target per frame
// of every take, and the animations are the asset's takes, in order, then the extra clips named
// on the command line. Exits 1 naming the first difference.
// usage: gltf_check ASSET GLB [EXTRA_CLIP...]
#include <fmt/format.h>

#include <string>
#include <vector>

#include "pipeline/core/error.h"
#include "pipeline/gltf/gltf.h"
#include "runtime/asset.h"

int main(int argc, char** argv) {
  using namespace fourd;
  if (argc < 3) {
    fmt::print(stderr, "usage: gltf_check ASSET GLB [EXTRA_CLIP...]\n");
    return kExitUsage;
  }
  try {
    const Asset asset = load_asset(argv[1]);
    const tinygltf::Model model = gltf::read_gltf(argv[2]);
    std::vector<std::string> expected;
    std::size_t take_frames = 0;
    for (const GraphSpace& space : asset.graph.spaces) {
      expected.insert(expected.end(), space.motion.takes.begin(), space.motion.takes.end());
      take_frames += static_cast<std::size_t>(space.num_inputs()) * space.num_samples();
    }
    for (int i = 3; i < argc; ++i) expected.emplace_back(argv[i]);
    std::vector<std::string> failures;
    if (model.meshes.size() != 1 || model.meshes[0].primitives.size() != 1) {
      failures.push_back(fmt::format("{} meshes, expected one with one primitive", model.meshes.size()));
    } else {
      const tinygltf::Primitive& p = model.meshes[0].primitives[0];
      const std::size_t vertices = model.accessors.at(p.attributes.at("POSITION")).count;
      const std::size_t asset_vertices = asset.graph.num_vertices();
      const bool split = p.attributes.count("TEXCOORD_0") > 0;
      fmt::print("vertices: glb {}, asset {}{}\n", vertices, asset_vertices,
                 split ? " (split at UV seams)" : "");
      if (!asset.graph.textures.empty() && (!split || model.images.size() != 1 ||
                                             model.materials.size() != 1))
        failures.push_back(fmt::format("the asset has textures: expected UVs and one image, got "
                                       "{} UVs, {} images",
                                       split ? "" : "no", model.images.size()));
      if (split ? vertices < asset_vertices : vertices != asset_vertices)
        failures.push_back(fmt::format("{} vertices, the asset has {}", vertices, asset_vertices));
      fmt::print("morph targets: {} ({} take frames)\n", p.targets.size(), take_frames);
      if (p.targets.size() < take_frames)
        failures.push_back(fmt::format("{} morph targets for {} take frames", p.targets.size(),
                                       take_frames));
    }
    std::vector<std::string> clips;
    for (const tinygltf::Animation& a : model.animations) clips.push_back(a.name);
    fmt::print("clips: {}\n", fmt::join(clips, ", "));
    if (clips != expected)
      failures.push_back(fmt::format("clips [{}], expected [{}]", fmt::join(clips, ", "),
                                     fmt::join(expected, ", ")));
    for (const std::string& f : failures) fmt::print(stderr, "{}: {}\n", argv[2], f);
    return failures.empty() ? kExitOk : kExitFailure;
  } catch (const Error& e) {
    fmt::print(stderr, "gltf_check: {}\n", e.what());
    return e.exit_code();
  }
}
