#include "pipeline/core/mesh.h"

#include <fmt/format.h>

#include <Eigen/Geometry>
#include <limits>

#include "pipeline/core/error.h"

namespace fourd {
namespace {

void check_attribute_size(const std::string& what, const char* name, std::size_t size,
                          std::size_t expected) {
  if (size != 0 && size != expected) {
    throw InputError(fmt::format("{}: {} {} for {} vertices (must be 0 or one per vertex)", what,
                                 size, name, expected));
  }
}

// Every index of every triangle in [0, count).
void check_indices(const std::string& what, const char* name, const std::vector<Tri>& tris,
                   std::size_t count) {
  for (std::size_t f = 0; f < tris.size(); ++f) {
    for (int k = 0; k < 3; ++k) {
      int i = tris[f][k];
      if (i < 0 || static_cast<std::size_t>(i) >= count) {
        throw InputError(
            fmt::format("{}: {} {} refers to index {} of {}", what, name, f, i, count));
      }
    }
  }
}

template <class Vec>
void check_finite(const std::string& what, const char* name, const std::vector<Vec>& values) {
  for (std::size_t i = 0; i < values.size(); ++i) {
    if (!values[i].allFinite()) {
      throw InputError(fmt::format("{}: {} {} is not finite", what, name, i));
    }
  }
}

}  // namespace

void Mesh::check(const std::string& what) const {
  const std::size_t nv = positions.size();
  check_indices(what, "triangle", triangles, nv);
  check_attribute_size(what, "normals", normals.size(), nv);
  check_attribute_size(what, "colors", colors.size(), nv);
  check_attribute_size(what, "confidence", confidence.size(), nv);
  for (std::size_t i = 0; i < confidence.size(); ++i) {
    if (!(confidence[i] >= 0 && confidence[i] <= 1)) {
      throw InputError(fmt::format("{}: vertex {} has confidence {}, expected 0..1", what, i,
                                   confidence[i]));
    }
  }
  if (uv_triangles.empty()) {
    check_attribute_size(what, "texture coordinates", uvs.size(), nv);
  } else {
    if (uv_triangles.size() != triangles.size()) {
      throw InputError(fmt::format("{}: {} UV triangles for {} triangles", what,
                                   uv_triangles.size(), triangles.size()));
    }
    check_indices(what, "UV triangle", uv_triangles, uvs.size());
  }
  check_finite(what, "vertex", positions);
  check_finite(what, "normal", normals);
  check_finite(what, "texture coordinate", uvs);
}

void compute_vertex_normals(Mesh& mesh) {
  mesh.normals.assign(mesh.positions.size(), Vec3f::Zero());
  for (const Tri& t : mesh.triangles) {
    const Vec3f& a = mesh.positions[t[0]];
    // The cross product's length is twice the triangle area: summing it weights by area.
    Vec3f n = (mesh.positions[t[1]] - a).cross(mesh.positions[t[2]] - a);
    for (int k = 0; k < 3; ++k) mesh.normals[t[k]] += n;
  }
  for (Vec3f& n : mesh.normals) {
    float length = n.norm();
    n = length > 0 ? Vec3f(n / length) : Vec3f::Zero();
  }
}

void bounding_box(const Mesh& mesh, Vec3f* lo, Vec3f* hi) {
  *lo = Vec3f::Constant(std::numeric_limits<float>::max());
  *hi = Vec3f::Constant(std::numeric_limits<float>::lowest());
  for (const Vec3f& p : mesh.positions) {
    *lo = lo->cwiseMin(p);
    *hi = hi->cwiseMax(p);
  }
}

}  // namespace fourd
