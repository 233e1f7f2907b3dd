#pragma once
// The animatable asset: everything the runtime needs, in one versioned binary file
// (pipeline/core/binary_format.h: magic "FOURDAS", version, byte order, checksum). Written by
// the graph stage into <session>/asset/; the runtime loads it with nothing else from the
// session.
//
// Payload (version 1), in order:
//   string name; double fps; SimilarityDefinition; TransitionOptions (the defaults the graph
//   was built for);
//   uint64 #spaces, per space: name, cyclic, takes, character height, triangles, blend space
//     (inputs, vertices, samples, plane stride, reference weights, frames, cells), normals
//     (same layout as the frames), roots, seconds, parameter map (name, unit, inputs, path,
//     values); (version 4) the blend space's frames are the inputs' in float followed by the
//     other references' fp16 displacements (runtime/blend.h), and so are the normals; before,
//     every reference's frames and normals in float, converted to displacements at load;
//   uint64 #edges, per edge: from, to, self-loop, similarity sizes, d_max, values, precomputed
//     transitions;
//   (version 5) per space, int32 default successor (GraphSpace::default_successor; before, the
//     loader applies choose_default_successor's rule);
//   (version 6) each space starts with a byte: 0 its geometry as above, 1 packed (the web
//     package, runtime/asset_packing.h: empty frames, displacements and normals, then the
//     packed geometry); a web package is such a file inside gzip;
//   (version 3) uint8 has textures; if 1: int32 width, height, JPEG quality; corner UVs
//     (#F x 3 Vec2f); uint64 #spaces, per space: int32 keys; then uint64 #images, each the bytes
//     of a JPEG file (runtime/textures.h). Version 2 files load without textures.
#include <filesystem>

#include "runtime/motion_graph.h"
#include "runtime/transition.h"

namespace fourd {

// 2: per-cell arc angles of the hybrid blend; 3: textures (atlas UVs, key textures per space);
// 4: references as fp16 displacements (positions and normals); 5: every space's default
// successor; 6: packed geometry (the web package). Versions 2 to 5 still load.
inline constexpr std::uint32_t kAssetVersion = 6;
inline constexpr std::uint32_t kAssetVersionDisplacements = 4;
inline constexpr std::uint32_t kAssetVersionSuccessors = 5;
inline constexpr std::uint32_t kAssetVersionPacked = 6;

struct Asset {
  MotionGraph graph;
  TransitionOptions transitions;  // the options the graph was built and evaluated with
};

// Checks the graph (MotionGraph::check) and writes the file atomically. Throws InputError for an
// inconsistent graph, IoError when the file cannot be written.
void save_asset(const std::filesystem::path& path, const Asset& asset);

// The web package (runtime/asset_packing.h, docs/web.md): the same file with every space's
// geometry packed, gzip-compressed, written atomically. load_asset reads it (natively; the web
// build has no zlib, and the page inflates it first). Throws ConfigError for bad `packing`,
// InputError as save_asset and for geometry the grids cannot hold.
struct AssetPacking;
void save_web_package(const std::filesystem::path& path, const Asset& asset,
                      const AssetPacking& packing);

// Throws IoError when the file cannot be read and InputError naming the file for a wrong magic,
// an unknown version, a truncated or corrupt file, inconsistent content, or a key texture that
// does not decode to the announced size.
Asset load_asset(const std::filesystem::path& path);

}  // namespace fourd
