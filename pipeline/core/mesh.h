#pragma once
// Triangle mesh as flat arrays (struct of arrays). Optional attributes are empty when absent.
#include <Eigen/Core>
#include <cstdint>
#include <string>
#include <vector>

namespace fourd {

using Vec3f = Eigen::Vector3f;
using Vec2f = Eigen::Vector2f;
using Tri = Eigen::Vector3i;
using Rgb8 = Eigen::Matrix<std::uint8_t, 3, 1>;

struct Mesh {
  std::vector<Vec3f> positions;  // #V, metres
  std::vector<Tri> triangles;    // #F, counter-clockwise seen from outside
  std::vector<Vec3f> normals;    // #V or empty
  std::vector<Rgb8> colors;      // #V or empty
  // Per-vertex confidence in [0, 1] (PLY property "confidence"), #V or empty. Reconstruct's:
  // 0 where only the visual hull placed the surface, towards 1 the more cameras measured it.
  std::vector<float> confidence;
  // Texture coordinates. Either per vertex (uvs.size() == #V, uv_triangles empty) or per
  // corner (uv_triangles.size() == #F indexing into uvs), as OBJ stores them at UV seams.
  std::vector<Vec2f> uvs;
  std::vector<Tri> uv_triangles;
  std::string texture;  // diffuse texture image, relative to the mesh file

  std::size_t num_vertices() const { return positions.size(); }
  std::size_t num_triangles() const { return triangles.size(); }
  bool empty() const { return positions.empty() || triangles.empty(); }

  // Throws InputError (prefixed by `what`) if an index is out of range, an attribute has the
  // wrong size or a coordinate is not finite.
  void check(const std::string& what) const;
};

// Area-weighted vertex normals, unit length (zero for isolated vertices).
void compute_vertex_normals(Mesh& mesh);
// Axis-aligned bounding box of the positions (empty, lo > hi, when there are none).
void bounding_box(const Mesh& mesh, Vec3f* lo, Vec3f* hi);
// Eigen view of the positions as a 3 x #V matrix without copying.
inline Eigen::Map<Eigen::Matrix3Xf> positions_matrix(Mesh& mesh) {
  return {mesh.positions.empty() ? nullptr : mesh.positions[0].data(), 3,
          static_cast<Eigen::Index>(mesh.positions.size())};
}
inline Eigen::Map<const Eigen::Matrix3Xf> positions_matrix(const Mesh& mesh) {
  return {mesh.positions.empty() ? nullptr : mesh.positions[0].data(), 3,
          static_cast<Eigen::Index>(mesh.positions.size())};
}

}  // namespace fourd
