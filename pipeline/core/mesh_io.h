#pragma once
// Mesh files.
// PLY: binary little-endian (written by default), ASCII, and big-endian (read only).
//   Vertices x y z, optional nx ny nz, red green blue (uchar), texture coordinates "s t"
//   (read also "u v", "texture_u texture_v"); faces "vertex_indices" (read also
//   "vertex_index"; polygons are fan-triangulated). Per-corner texture coordinates and the
//   texture name follow MeshLab: a face list "texcoord" and "comment TextureFile <name>".
//   Properties of any numeric type are converted; unknown properties and elements are skipped.
// OBJ: v (with optional r g b), vt, vn, f in every v/vt/vn form with negative indices;
//   per-corner UVs map to Mesh::uv_triangles unless every corner uses its vertex's index.
//   When the mesh has a texture, a .mtl beside the .obj names it with map_Kd.
// All writers are atomic. Readers throw InputError naming the file and line (text) or
// element (binary) for malformed content, "truncated" for a file that ends early, and
// IoError when the file cannot be read.
#include <filesystem>

#include "pipeline/core/mesh.h"

namespace fourd {

enum class PlyFormat { kBinary, kAscii };

Mesh read_ply(const std::filesystem::path& path);
void write_ply(const std::filesystem::path& path, const Mesh& mesh,
               PlyFormat format = PlyFormat::kBinary);

// Writes `path` (.obj) and, when the mesh has a texture, <stem>.mtl beside it.
Mesh read_obj(const std::filesystem::path& path);
void write_obj(const std::filesystem::path& path, const Mesh& mesh);

// Dispatch on the extension (.ply / .obj).
Mesh read_mesh(const std::filesystem::path& path);
void write_mesh(const std::filesystem::path& path, const Mesh& mesh);

}  // namespace fourd
