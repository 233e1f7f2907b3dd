#pragma once
// glTF 2.0 through tinygltf, shared by the synth stage's importer/exporter and the runtime's
// exporter (fourd-export). gltf.cpp is the one translation unit that compiles tinygltf.
//
// Axes: glTF is y-up with the asset facing +z; our world is z-up facing +x. The two are related
// by one fixed rotation that maps glTF +z (front) to our +x, glTF +x (the character's left) to
// our +y and glTF +y (up) to our +z: our = kOurFromGltf * gltf.
//
// Images: Debian ships no stb headers, so tinygltf is built without its image coders; images
// are decoded with OpenCV on read, and written as encoded bytes (PNG, JPEG, WebP) straight into
// a buffer view.
//
// Compression: EXT_meshopt_compression (meshoptimizer's vertex and index codecs, Debian's
// libmeshoptimizer-dev). A compressed buffer view holds the codec's bytes in the GLB's buffer 0
// while the view itself points into a second, "fallback" buffer with no data; tinygltf cannot
// write view or buffer extensions, so write_glb patches the JSON of the views BufferWriter made
// compressed (BufferWriter::meshopt_views).
#define TINYGLTF_NO_STB_IMAGE
#define TINYGLTF_NO_STB_IMAGE_WRITE
#include <tiny_gltf.h>

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <algorithm>
#include <cstdint>
#include <filesystem>
#include <limits>
#include <span>
#include <vector>

#include "pipeline/core/mesh.h"

namespace fourd::gltf {

// our = kOurFromGltf * gltf: glTF +z (front) -> our +x, +x (left) -> +y, +y (up) -> +z.
inline const Eigen::Matrix3d kOurFromGltf =
    (Eigen::Matrix3d() << 0, 0, 1, 1, 0, 0, 0, 1, 0).finished();

// A point or direction of our world in glTF axes.
inline Eigen::Vector3f to_gltf(const Vec3f& ours) {
  return kOurFromGltf.transpose().cast<float>() * ours;
}
inline Eigen::Vector3d to_gltf(const Eigen::Vector3d& ours) {
  return kOurFromGltf.transpose() * ours;
}
// A rigid transform (rotation) of our world expressed in glTF axes: conjugation by the axes
// rotation, so a joint frame axis-aligned here is axis-aligned there.
Eigen::Matrix4d to_gltf_axes(const Eigen::Matrix4d& ours);
Eigen::Quaterniond to_gltf_axes(const Eigen::Quaterniond& ours);

// An EXT_meshopt_compression buffer view: `count` elements of `stride` bytes, encoded with the
// attribute codec (kAttributes: stride a multiple of 4, at most 256) or the triangle index codec
// (kTriangles: stride 2 or 4, count a multiple of 3).
enum class MeshoptMode { kAttributes, kTriangles };
struct MeshoptView {
  int view = 0;  // index in model.bufferViews
  std::size_t stride = 0, count = 0;
  MeshoptMode mode = MeshoptMode::kAttributes;
};

// Appends typed arrays to the single buffer of `model`, each with its own buffer view and
// accessor.
class BufferWriter {
 public:
  explicit BufferWriter(tinygltf::Model& model) : model_(model) { model_.buffers.resize(1); }

  // A buffer view over a copy of `bytes` (4-byte aligned); target 0 for none. Returns its index.
  int add_view(const void* bytes, std::size_t size, int target);
  // A view of `count` elements of `stride` bytes at `bytes`, compressed with meshoptimizer's
  // codec for `mode` (see MeshoptView); vertex attribute views (target ARRAY_BUFFER) get the
  // stride as byteStride. Returns its index.
  int add_meshopt_view(const void* bytes, std::size_t count, std::size_t stride, MeshoptMode mode,
                       int target);
  // An accessor of `count` elements of `type` (`component_type` components) over a compressed
  // view of `values`, `stride` bytes per element (an element may be padded to the stride: its
  // first components are the accessor's, min/max taken over those).
  template <class T>
  int add_meshopt_accessor(const std::vector<T>& values, std::size_t count, std::size_t stride,
                           int component_type, int type, int target, bool normalized,
                           bool with_bounds = false, MeshoptMode mode = MeshoptMode::kAttributes) {
    const int components = tinygltf::GetNumComponentsInType(type);
    const std::size_t per_element = stride / sizeof(T);
    tinygltf::Accessor accessor;
    accessor.bufferView = add_meshopt_view(values.data(), count, stride, mode, target);
    accessor.componentType = component_type;
    accessor.type = type;
    accessor.count = count;
    accessor.normalized = normalized;
    if (with_bounds) {
      accessor.minValues.assign(components, std::numeric_limits<double>::infinity());
      accessor.maxValues.assign(components, -std::numeric_limits<double>::infinity());
      for (std::size_t e = 0; e < count; ++e) {
        for (int c = 0; c < components; ++c) {
          const double v = static_cast<double>(values[e * per_element + c]);
          accessor.minValues[c] = std::min(accessor.minValues[c], v);
          accessor.maxValues[c] = std::max(accessor.maxValues[c], v);
        }
      }
    }
    model_.accessors.push_back(accessor);
    return static_cast<int>(model_.accessors.size()) - 1;
  }
  // The compressed views so far, for write_glb.
  const std::vector<MeshoptView>& meshopt_views() const { return meshopt_; }

  // An accessor over count * components(type) elements of `T`. min/max are written when
  // `with_bounds` (required for POSITION, morph target POSITION and animation inputs).
  template <class T>
  int add_accessor(std::span<const T> values, int component_type, int type, int target,
                   bool with_bounds = false) {
    const int components = tinygltf::GetNumComponentsInType(type);
    tinygltf::Accessor accessor;
    accessor.bufferView = add_view(values.data(), values.size() * sizeof(T), target);
    accessor.componentType = component_type;
    accessor.type = type;
    accessor.count = values.size() / components;
    if (with_bounds) {
      accessor.minValues.assign(components, std::numeric_limits<double>::infinity());
      accessor.maxValues.assign(components, -std::numeric_limits<double>::infinity());
      for (std::size_t i = 0; i < values.size(); ++i) {
        const int c = static_cast<int>(i % components);
        accessor.minValues[c] = std::min(accessor.minValues[c], static_cast<double>(values[i]));
        accessor.maxValues[c] = std::max(accessor.maxValues[c], static_cast<double>(values[i]));
      }
    }
    model_.accessors.push_back(accessor);
    return static_cast<int>(model_.accessors.size()) - 1;
  }
  template <class T>
  int add_accessor(const std::vector<T>& values, int component_type, int type, int target,
                   bool with_bounds = false) {
    return add_accessor(std::span<const T>(values), component_type, type, target, with_bounds);
  }

  // An embedded PNG image with a linear, mipmapped sampler and a texture over it; returns the
  // texture index (for a material's baseColorTexture).
  int add_png_texture(std::span<const unsigned char> png, const std::string& name);
  // The same for an image of another type (`mime_type`: image/png, image/jpeg, image/webp).
  int add_image_texture(std::span<const unsigned char> bytes, const std::string& mime_type,
                        const std::string& name);

 private:
  tinygltf::Model& model_;
  std::vector<MeshoptView> meshopt_;
};

// Adds a LINEAR channel to `animation`: node `node`'s `path` ("translation", "rotation",
// "weights") keyed at the times of accessor `input`, `values` (float, `type` per key); with
// `meshopt` the values' view is compressed (EXT_meshopt_compression).
void add_linear_channel(tinygltf::Animation* animation, BufferWriter& buffer, int input, int node,
                        const char* path, const std::vector<float>& values, int type,
                        bool meshopt = false);

// Rotation keys (x, y, z, w per key) of rotations of our world, in glTF axes, each in the
// hemisphere of the key before it so that every interpolator takes the short way.
std::vector<float> rotation_keys(std::span<const Eigen::Quaterniond> ours);

// glTF attributes are per vertex; a mesh with per-corner UVs is split at its UV seams.
struct ExportVertices {
  std::vector<int> source;     // per exported vertex: the mesh vertex it copies
  std::vector<int> uv;         // per exported vertex: its UV index (-1 without UVs)
  std::vector<Tri> triangles;  // in exported vertex indices
};
ExportVertices export_vertices(const Mesh& mesh);
// Reorders exported vertices and triangles for meshoptimizer's codecs (vertex cache order,
// then vertices in the order the triangles first use them, unused ones last): neighbouring
// vertices become neighbours in the buffers, which the delta coding of EXT_meshopt_compression
// compresses much better.
void order_for_compression(ExportVertices* vertices);

// A triangle primitive of `mesh` (our axes, #V normals) in glTF axes: POSITION, NORMAL,
// TEXCOORD_0 when `with_uvs` (the mesh's UVs, v flipped: glTF counts v from the top row) and
// the indices. `vertices` receives the split at UV seams (which mesh vertex each exported
// vertex copies), to write further attributes in the same order.
tinygltf::Primitive add_mesh_primitive(BufferWriter& buffer, const Mesh& mesh, bool with_uvs,
                                       ExportVertices* vertices);

// Serialises `model` as binary glTF (.glb) and writes it atomically. `meshopt`: the views
// BufferWriter compressed (their JSON gets the EXT_meshopt_compression extension over a
// fallback buffer, and the extension is declared used and required). Throws IoError naming the
// file when it cannot be serialised or written.
void write_glb(const std::filesystem::path& path, tinygltf::Model& model,
               std::span<const MeshoptView> meshopt = {});

// Reads a .gltf (with its buffers and images) or a .glb; images are decoded to 8-bit BGR
// (component 3). Throws IoError if the file cannot be read, InputError naming the file if it
// is not glTF that tinygltf can load.
tinygltf::Model read_gltf(const std::filesystem::path& path);

}  // namespace fourd::gltf
