#pragma once
// Mesh files: PLY (binary little-endian and ASCII; positions, triangles, optional normals,
// colours and per-vertex texture coordinates "s t" / "u v") and OBJ + MTL (positions,
// per-corner UVs, normals, map_Kd texture). All writers are atomic. Readers throw
// InputError naming the file and line/element for malformed content, IoError when the file
// cannot be read.
#include <filesystem>

#include "pipeline/core/mesh.h"

namespace fourd {

enum class PlyFormat { kBinary, kAscii };

Mesh read_ply(const std::filesystem::path& path);
void write_ply(const std::filesystem::path& path, const Mesh& mesh,
               PlyFormat format = PlyFormat::kBinary);

// Writes `path` (.obj) and, when the mesh has a texture or UVs, a .mtl beside it.
Mesh read_obj(const std::filesystem::path& path);
void write_obj(const std::filesystem::path& path, const Mesh& mesh);

// Dispatch on the extension (.ply / .obj).
Mesh read_mesh(const std::filesystem::path& path);
void write_mesh(const std::filesystem::path& path, const Mesh& mesh);

}  // namespace fourd
