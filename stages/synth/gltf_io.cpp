#include "stages/synth/gltf_io.h"

#include <fmt/format.h>

#include <Eigen/SVD>
#include <algorithm>
#include <cmath>
#include <cstring>
#include <map>
#include <numeric>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <set>

#include "pipeline/core/error.h"
#include "pipeline/core/files.h"
#include "pipeline/gltf/gltf.h"
#include "stages/synth/imported_clip.h"

namespace fourd::synth {
namespace {

// ---------------------------------------------------------------------------------------------
// Axes (pipeline/gltf/gltf.h): our = kOurFromGltf * gltf.

using gltf::BufferWriter;
using gltf::kOurFromGltf;
using gltf::to_gltf_axes;

Eigen::Matrix4d homogeneous(const Eigen::Matrix3d& linear) {
  Eigen::Matrix4d m = Eigen::Matrix4d::Identity();
  m.topLeftCorner<3, 3>() = linear;
  return m;
}

const Eigen::Matrix4d kOurFromGltf4 = homogeneous(kOurFromGltf);
const Eigen::Matrix4d kGltfFromOur4 = homogeneous(kOurFromGltf.transpose());

// The rotation closest to `m` (removes the scale of armatures exported in centimetres and the
// rounding of float storage).
Eigen::Matrix3d nearest_rotation(const Eigen::Matrix3d& m) {
  Eigen::JacobiSVD<Eigen::Matrix3d> svd(m, Eigen::ComputeFullU | Eigen::ComputeFullV);
  Eigen::Matrix3d u = svd.matrixU();
  if ((u * svd.matrixV().transpose()).determinant() < 0) u.col(2) *= -1;
  return u * svd.matrixV().transpose();
}

// ---------------------------------------------------------------------------------------------
// Writing.

void check_character(const std::string& file, const Character& character,
                     const std::vector<MotionClip>& clips) {
  const Skeleton& skeleton = character.skeleton;
  const std::size_t joints = skeleton.size();
  if (joints == 0 || skeleton.parents.size() != joints || skeleton.rest_offsets.size() != joints)
    throw InputError(fmt::format("{}: the skeleton of '{}' is empty or its arrays differ in size",
                                 file, character.name));
  for (std::size_t j = 0; j < joints; ++j) {
    const int parent = skeleton.parents[j];
    if (j == 0 ? parent != -1 : (parent < 0 || parent >= static_cast<int>(j)))
      throw InputError(fmt::format("{}: joint '{}' has parent {}, not in topological order", file,
                                   skeleton.names[j], parent));
  }
  const SkinnedMesh& skin = character.skin;
  const std::size_t vertices = skin.rest.num_vertices();
  if (skin.rest.empty() || skin.joints.size() != vertices || skin.weights.size() != vertices ||
      skin.inverse_bind.size() != joints)
    throw InputError(fmt::format(
        "{}: the skinned mesh of '{}' is empty or its joints/weights/inverse_bind sizes differ",
        file, character.name));
  for (std::size_t v = 0; v < vertices; ++v)
    for (int k = 0; k < 4; ++k)
      if (skin.joints[v][k] < 0 || skin.joints[v][k] >= static_cast<int>(joints))
        throw InputError(fmt::format("{}: vertex {} references joint {} of {}", file, v,
                                     skin.joints[v][k], joints));
  if (!skin.rest.uvs.empty() && skin.rest.uv_triangles.empty() && skin.rest.uvs.size() != vertices)
    throw InputError(fmt::format("{}: per-vertex UVs of '{}' do not match its vertex count", file,
                                 character.name));
  if (!skin.rest.uv_triangles.empty() && skin.rest.uv_triangles.size() != skin.rest.num_triangles())
    throw InputError(fmt::format("{}: per-corner UVs of '{}' do not match its triangle count", file,
                                 character.name));
  if (!character.texture.empty() && character.texture.depth() != CV_8U)
    throw InputError(fmt::format("{}: the texture of '{}' is not 8-bit", file, character.name));
  for (const MotionClip& clip : clips) {
    if (clip.poses.empty() || !(clip.fps > 0))
      throw InputError(
          fmt::format("{}: take '{}' has no frames or no frame rate", file, clip.spec.take));
    for (std::size_t f = 0; f < clip.poses.size(); ++f)
      if (clip.poses[f].local_rotations.size() != joints)
        throw InputError(fmt::format("{}: take '{}' frame {} has {} joint rotations, not {}", file,
                                     clip.spec.take, f, clip.poses[f].local_rotations.size(),
                                     joints));
  }
}

void add_mesh(tinygltf::Model& model, BufferWriter& buffer, const Character& character) {
  const SkinnedMesh& skin = character.skin;
  Mesh rest = skin.rest;
  if (rest.normals.size() != rest.num_vertices()) compute_vertex_normals(rest);
  const bool has_uvs = !rest.uvs.empty();
  gltf::ExportVertices vertices;
  tinygltf::Primitive primitive = gltf::add_mesh_primitive(buffer, rest, has_uvs, &vertices);
  std::vector<float> weights;
  std::vector<std::uint16_t> joints;
  for (const int v : vertices.source) {
    for (int k = 0; k < 4; ++k) {
      // Validators flag unused slots that name a joint: give them joint 0.
      const bool used = skin.weights[v][k] != 0;
      joints.push_back(static_cast<std::uint16_t>(used ? skin.joints[v][k] : 0));
      weights.push_back(skin.weights[v][k]);
    }
  }
  constexpr int kArray = TINYGLTF_TARGET_ARRAY_BUFFER;
  primitive.attributes["JOINTS_0"] = buffer.add_accessor(
      joints, TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT, TINYGLTF_TYPE_VEC4, kArray);
  primitive.attributes["WEIGHTS_0"] =
      buffer.add_accessor(weights, TINYGLTF_COMPONENT_TYPE_FLOAT, TINYGLTF_TYPE_VEC4, kArray);

  tinygltf::Material material;
  material.name = character.name.empty() ? "material" : character.name;
  material.pbrMetallicRoughness.metallicFactor = 0;
  material.pbrMetallicRoughness.roughnessFactor = 1;
  if (has_uvs && !character.texture.empty()) {
    std::vector<unsigned char> png;
    if (!cv::imencode(".png", character.texture, png))
      throw InputError(fmt::format("cannot encode the texture of '{}' as PNG", character.name));
    material.pbrMetallicRoughness.baseColorTexture.index = buffer.add_png_texture(png, "texture");
  }
  model.materials.push_back(material);
  primitive.material = 0;

  tinygltf::Mesh mesh;
  mesh.name = character.name;
  mesh.primitives.push_back(primitive);
  model.meshes.push_back(mesh);
}

// Joint j is node j; the skinned mesh node follows the joints.
void add_skeleton(tinygltf::Model& model, BufferWriter& buffer, const Character& character) {
  const Skeleton& skeleton = character.skeleton;
  const int joints = static_cast<int>(skeleton.size());
  tinygltf::Skin skin;
  skin.name = character.name;
  skin.skeleton = 0;
  std::vector<float> inverse_bind;
  for (int j = 0; j < joints; ++j) {
    tinygltf::Node node;
    node.name = skeleton.names[j];
    const Eigen::Vector3d t = gltf::to_gltf(skeleton.rest_offsets[j]);
    node.translation = {t.x(), t.y(), t.z()};
    model.nodes.push_back(node);
    if (j > 0) model.nodes[skeleton.parents[j]].children.push_back(j);
    skin.joints.push_back(j);
    // Column-major, as glTF stores matrices.
    const Eigen::Matrix4d m = to_gltf_axes(character.skin.inverse_bind[j].matrix());
    for (int c = 0; c < 4; ++c)
      for (int r = 0; r < 4; ++r) inverse_bind.push_back(static_cast<float>(m(r, c)));
  }
  skin.inverseBindMatrices =
      buffer.add_accessor(inverse_bind, TINYGLTF_COMPONENT_TYPE_FLOAT, TINYGLTF_TYPE_MAT4, 0);
  model.skins.push_back(skin);

  tinygltf::Node mesh_node;
  mesh_node.name = character.name.empty() ? "character" : character.name;
  mesh_node.mesh = 0;
  mesh_node.skin = 0;
  model.nodes.push_back(mesh_node);

  tinygltf::Scene scene;
  scene.name = character.name;
  scene.nodes = {0, joints};
  model.scenes.push_back(scene);
  model.defaultScene = 0;
}

void add_animation(tinygltf::Model& model, BufferWriter& buffer, const MotionClip& clip) {
  const int frames = static_cast<int>(clip.poses.size());
  const int joints = static_cast<int>(clip.poses[0].local_rotations.size());
  tinygltf::Animation animation;
  animation.name = clip.spec.take;
  std::vector<float> times(frames);
  for (int f = 0; f < frames; ++f) times[f] = static_cast<float>(f / clip.fps);
  const int input =
      buffer.add_accessor(times, TINYGLTF_COMPONENT_TYPE_FLOAT, TINYGLTF_TYPE_SCALAR, 0, true);
  for (int j = 0; j < joints; ++j) {
    std::vector<Eigen::Quaterniond> rotations(frames);
    for (int f = 0; f < frames; ++f) rotations[f] = clip.poses[f].local_rotations[j];
    gltf::add_linear_channel(&animation, buffer, input, j, "rotation",
                             gltf::rotation_keys(rotations), TINYGLTF_TYPE_VEC4);
  }
  std::vector<float> translations;
  for (const Pose& pose : clip.poses) {
    const Eigen::Vector3d t = gltf::to_gltf(pose.root_position);
    translations.insert(translations.end(), {static_cast<float>(t.x()), static_cast<float>(t.y()),
                                             static_cast<float>(t.z())});
  }
  gltf::add_linear_channel(&animation, buffer, input, 0, "translation", translations,
                           TINYGLTF_TYPE_VEC3);
  model.animations.push_back(animation);
}

// ---------------------------------------------------------------------------------------------
// Reading.

const char* type_name(int type) {
  switch (type) {
    case TINYGLTF_TYPE_SCALAR:
      return "SCALAR";
    case TINYGLTF_TYPE_VEC2:
      return "VEC2";
    case TINYGLTF_TYPE_VEC3:
      return "VEC3";
    case TINYGLTF_TYPE_VEC4:
      return "VEC4";
    case TINYGLTF_TYPE_MAT2:
      return "MAT2";
    case TINYGLTF_TYPE_MAT3:
      return "MAT3";
    case TINYGLTF_TYPE_MAT4:
      return "MAT4";
    default:
      return "unknown type";
  }
}

const char* component_name(int component_type) {
  switch (component_type) {
    case TINYGLTF_COMPONENT_TYPE_BYTE:
      return "BYTE";
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE:
      return "UNSIGNED_BYTE";
    case TINYGLTF_COMPONENT_TYPE_SHORT:
      return "SHORT";
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT:
      return "UNSIGNED_SHORT";
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT:
      return "UNSIGNED_INT";
    case TINYGLTF_COMPONENT_TYPE_FLOAT:
      return "FLOAT";
    default:
      return "unknown component type";
  }
}

// What a field accepts: its accessor type, and its component types with the normalisation they
// must have (integers standing for [0,1] in weights, UVs and rotations).
struct Accepts {
  int type;
  std::vector<std::pair<int, bool>> components;  // (component type, normalized)
};

const std::pair<int, bool> kFloat{TINYGLTF_COMPONENT_TYPE_FLOAT, false};
const std::pair<int, bool> kUByteNorm{TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE, true};
const std::pair<int, bool> kUShortNorm{TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT, true};
const std::pair<int, bool> kByteNorm{TINYGLTF_COMPONENT_TYPE_BYTE, true};
const std::pair<int, bool> kShortNorm{TINYGLTF_COMPONENT_TYPE_SHORT, true};
const std::pair<int, bool> kUByte{TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE, false};
const std::pair<int, bool> kUShort{TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT, false};
const std::pair<int, bool> kUInt{TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT, false};

// An accessor's elements as doubles, row-major: count x components.
struct Table {
  std::size_t count = 0;
  int components = 0;
  std::vector<double> values;
  double at(std::size_t row, int c) const { return values[row * components + c]; }
};

double decode_component(const unsigned char* p, int component_type, bool normalized) {
  switch (component_type) {
    case TINYGLTF_COMPONENT_TYPE_BYTE: {
      std::int8_t v;
      std::memcpy(&v, p, 1);
      return normalized ? std::max(v / 127.0, -1.0) : v;
    }
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE:
      return normalized ? *p / 255.0 : *p;
    case TINYGLTF_COMPONENT_TYPE_SHORT: {
      std::int16_t v;
      std::memcpy(&v, p, 2);
      return normalized ? std::max(v / 32767.0, -1.0) : v;
    }
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT: {
      std::uint16_t v;
      std::memcpy(&v, p, 2);
      return normalized ? v / 65535.0 : v;
    }
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT: {
      std::uint32_t v;
      std::memcpy(&v, p, 4);
      return v;
    }
    default: {
      float v;
      std::memcpy(&v, p, 4);
      return v;
    }
  }
}

class GltfReader {
 public:
  GltfReader(std::string file, const tinygltf::Model& model)
      : file_(std::move(file)), model_(model) {}

  [[noreturn]] void fail(const std::string& what) const {
    throw InputError(fmt::format("{}: {}", file_, what));
  }

  // Reads accessor `index` for `what` (named in errors), checking it is of an accepted kind.
  Table read(int index, const Accepts& accepts, const std::string& what) const {
    if (index < 0 || index >= static_cast<int>(model_.accessors.size()))
      fail(fmt::format("{}: accessor {} does not exist", what, index));
    const tinygltf::Accessor& a = model_.accessors[index];
    if (a.type != accepts.type)
      fail(fmt::format("{}: accessor {} is {}, expected {}", what, index, type_name(a.type),
                       type_name(accepts.type)));
    const bool accepted =
        std::any_of(accepts.components.begin(), accepts.components.end(), [&](const auto& c) {
          return c.first == a.componentType &&
                 (c.second == a.normalized || c.first == TINYGLTF_COMPONENT_TYPE_FLOAT);
        });
    if (!accepted) {
      std::string allowed;
      for (const auto& c : accepts.components)
        allowed += fmt::format("{}{}{}", allowed.empty() ? "" : ", ", component_name(c.first),
                               c.second ? " (normalized)" : "");
      fail(fmt::format("{}: accessor {} has components {}{}, expected {}", what, index,
                       component_name(a.componentType), a.normalized ? " (normalized)" : "",
                       allowed));
    }
    Table table;
    table.count = a.count;
    table.components = tinygltf::GetNumComponentsInType(a.type);
    const int component_size = tinygltf::GetComponentSizeInBytes(a.componentType);
    const std::size_t element_size = static_cast<std::size_t>(component_size) * table.components;
    if (a.bufferView >= 0) {
      const unsigned char* data = view_data(a.bufferView, what);
      const tinygltf::BufferView& view = model_.bufferViews[a.bufferView];
      const std::size_t stride = view.byteStride ? view.byteStride : element_size;
      // Compared without multiplying out, so a huge count or offset cannot wrap around.
      if (a.count > 0 && (a.byteOffset > view.byteLength ||
                          element_size > view.byteLength - a.byteOffset ||
                          (a.count - 1) > (view.byteLength - a.byteOffset - element_size) / stride))
        fail(fmt::format("{}: accessor {} reads past the end of buffer view {}", what, index,
                         a.bufferView));
      table.values.resize(table.count * table.components);
      for (std::size_t i = 0; i < a.count; ++i)
        for (int c = 0; c < table.components; ++c)
          table.values[i * table.components + c] = decode_component(
              data + a.byteOffset + i * stride + c * component_size, a.componentType, a.normalized);
    } else {
      if (!a.sparse.isSparse || a.count > (std::size_t{1} << 26))
        fail(fmt::format("{}: accessor {} has no data (no buffer view)", what, index));
      table.values.assign(table.count * table.components, 0.0);  // zeros under the sparse ones
    }
    if (a.sparse.isSparse) apply_sparse(a, index, what, element_size, table);
    for (double v : table.values)
      if (!std::isfinite(v))
        fail(fmt::format("{}: accessor {} holds a non-finite value", what, index));
    return table;
  }

  const std::string& file() const { return file_; }

 private:
  const unsigned char* view_data(int view_index, const std::string& what) const {
    if (view_index < 0 || view_index >= static_cast<int>(model_.bufferViews.size()))
      fail(fmt::format("{}: buffer view {} does not exist", what, view_index));
    const tinygltf::BufferView& view = model_.bufferViews[view_index];
    if (view.buffer < 0 || view.buffer >= static_cast<int>(model_.buffers.size()) ||
        view.byteOffset + view.byteLength > model_.buffers[view.buffer].data.size())
      fail(fmt::format("{}: buffer view {} lies outside its buffer", what, view_index));
    return model_.buffers[view.buffer].data.data() + view.byteOffset;
  }

  // Sparse accessors replace some elements of the dense ones (or of zeros).
  void apply_sparse(const tinygltf::Accessor& a, int index, const std::string& what,
                    std::size_t element_size, Table& table) const {
    const int n = a.sparse.count;
    const int index_type = a.sparse.indices.componentType;
    const int index_size = tinygltf::GetComponentSizeInBytes(index_type);
    if (index_type != TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE &&
        index_type != TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT &&
        index_type != TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT)
      fail(fmt::format("{}: sparse accessor {} has indices of type {}", what, index,
                       component_name(index_type)));
    const unsigned char* indices = view_data(a.sparse.indices.bufferView, what);
    const unsigned char* values = view_data(a.sparse.values.bufferView, what);
    const tinygltf::BufferView& index_view = model_.bufferViews[a.sparse.indices.bufferView];
    const tinygltf::BufferView& value_view = model_.bufferViews[a.sparse.values.bufferView];
    if (a.sparse.indices.byteOffset + static_cast<std::size_t>(n) * index_size >
            index_view.byteLength ||
        a.sparse.values.byteOffset + n * element_size > value_view.byteLength)
      fail(fmt::format("{}: sparse accessor {} reads past its buffer views", what, index));
    const int component_size = tinygltf::GetComponentSizeInBytes(a.componentType);
    for (int s = 0; s < n; ++s) {
      const auto row = static_cast<std::size_t>(decode_component(
          indices + a.sparse.indices.byteOffset + s * index_size, index_type, false));
      if (row >= table.count)
        fail(fmt::format("{}: sparse accessor {} replaces element {} of {}", what, index, row,
                         table.count));
      for (int c = 0; c < table.components; ++c)
        table.values[row * table.components + c] = decode_component(
            values + a.sparse.values.byteOffset + s * element_size + c * component_size,
            a.componentType, a.normalized);
    }
  }

  std::string file_;
  const tinygltf::Model& model_;
};

// A node's local transform as translation, rotation, scale (a matrix is decomposed).
struct Trs {
  Eigen::Vector3d t = Eigen::Vector3d::Zero();
  Eigen::Quaterniond r = Eigen::Quaterniond::Identity();
  Eigen::Vector3d s = Eigen::Vector3d::Ones();

  Eigen::Matrix4d matrix() const {
    Eigen::Matrix4d m = Eigen::Matrix4d::Identity();
    m.topLeftCorner<3, 3>() = r.normalized().toRotationMatrix() * s.asDiagonal();
    m.topRightCorner<3, 1>() = t;
    return m;
  }
};

Trs node_trs(const tinygltf::Node& node) {
  Trs trs;
  if (node.matrix.size() == 16) {
    Eigen::Matrix4d m;
    for (int c = 0; c < 4; ++c)
      for (int r = 0; r < 4; ++r) m(r, c) = node.matrix[c * 4 + r];
    trs.t = m.topRightCorner<3, 1>();
    Eigen::Matrix3d linear = m.topLeftCorner<3, 3>();
    for (int c = 0; c < 3; ++c) trs.s[c] = linear.col(c).norm();
    if (linear.determinant() < 0) trs.s[0] = -trs.s[0];  // a mirror: keep it in the scale
    for (int c = 0; c < 3; ++c)
      if (trs.s[c] != 0) linear.col(c) /= trs.s[c];
    trs.r = Eigen::Quaterniond(nearest_rotation(linear));
    return trs;
  }
  if (node.translation.size() == 3)
    trs.t = {node.translation[0], node.translation[1], node.translation[2]};
  if (node.rotation.size() == 4)
    trs.r =
        Eigen::Quaterniond(node.rotation[3], node.rotation[0], node.rotation[1], node.rotation[2]);
  if (node.scale.size() == 3) trs.s = {node.scale[0], node.scale[1], node.scale[2]};
  return trs;
}

// The joints of the first skin, in our skeleton's order.
struct SkinJoint {
  int node = -1;        // glTF node, -1 for an added root joint that stays at the origin
  int skin_index = -1;  // index in skin.joints (what JOINTS_n refer to), -1 if added
  Eigen::Matrix4d inverse_bind = Eigen::Matrix4d::Identity();  // glTF axes
};

class CharacterImporter {
 public:
  CharacterImporter(const std::string& file, const tinygltf::Model& model,
                    const GltfImportOptions& options)
      : reader_(file, model), model_(model), options_(options) {}

  ImportedCharacter run() {
    check_extensions();
    if (model_.skins.empty()) reader_.fail("no skin (the character must be a skinned mesh)");
    build_parents();
    build_joints();
    ImportedCharacter out;
    out.character.name = character_name();
    build_skeleton(out.character);
    build_mesh(out.character);
    std::set<std::string> takes;
    for (std::size_t a = 0; a < model_.animations.size(); ++a) {
      const std::string base = model_.animations[a].name.empty() ? fmt::format("animation{}", a)
                                                                 : model_.animations[a].name;
      std::string take = base;
      for (int k = 2; takes.count(take); ++k) take = fmt::format("{}_{}", base, k);
      takes.insert(take);
      out.clips.push_back(sample_animation(static_cast<int>(a), take, out.character.skeleton));
    }
    return out;
  }

 private:
  // Required extensions that change how geometry or images are stored (Draco, meshopt,
  // quantisation, Basis textures) would be misread; material and light extensions only change
  // shading, which we do not use.
  void check_extensions() const {
    std::string unsupported;
    for (const std::string& e : model_.extensionsRequired) {
      const bool harmless = e.starts_with("KHR_materials_") || e == "KHR_lights_punctual" ||
                            e == "KHR_texture_transform";
      if (!harmless) unsupported += (unsupported.empty() ? "" : ", ") + e;
    }
    if (!unsupported.empty())
      reader_.fail("requires glTF extensions that are not supported: " + unsupported +
                   " (re-export without compression)");
  }

  void build_parents() {
    parent_.assign(model_.nodes.size(), -1);
    for (std::size_t n = 0; n < model_.nodes.size(); ++n)
      for (int child : model_.nodes[n].children) {
        if (child < 0 || child >= static_cast<int>(model_.nodes.size()) || parent_[child] != -1)
          reader_.fail(fmt::format("node {} has an invalid or shared child {}", n, child));
        parent_[child] = static_cast<int>(n);
      }
    // A cycle would make the parent walks below endless.
    for (std::size_t n = 0; n < model_.nodes.size(); ++n) {
      int p = parent_[n];
      for (std::size_t steps = 0; p >= 0; p = parent_[p])
        if (++steps > model_.nodes.size()) reader_.fail(fmt::format("node {} is in a cycle", n));
    }
    rest_.resize(model_.nodes.size());
    for (std::size_t n = 0; n < model_.nodes.size(); ++n) rest_[n] = node_trs(model_.nodes[n]);
  }

  Eigen::Matrix4d global(int node, const std::vector<Trs>& local) const {
    Eigen::Matrix4d m = Eigen::Matrix4d::Identity();
    for (int n = node; n >= 0; n = parent_[n]) m = local[n].matrix() * m;
    return m;
  }

  // Orders the skin's joints parent-first, giving every joint the nearest ancestor node that
  // is a joint as its parent. Several root joints are gathered under their lowest common
  // ancestor node (or an added root) because our skeleton has a single root.
  void build_joints() {
    const tinygltf::Skin& skin = model_.skins[0];
    if (skin.joints.empty()) reader_.fail("skin 0 has no joints");
    std::map<int, int> skin_index;  // node -> index in skin.joints
    for (std::size_t i = 0; i < skin.joints.size(); ++i) {
      const int node = skin.joints[i];
      if (node < 0 || node >= static_cast<int>(model_.nodes.size()) ||
          !skin_index.emplace(node, static_cast<int>(i)).second)
        reader_.fail(fmt::format("skin 0: joint {} is not a node or is listed twice", node));
    }
    std::vector<Eigen::Matrix4d> inverse_binds(skin.joints.size(), Eigen::Matrix4d::Identity());
    if (skin.inverseBindMatrices >= 0) {
      const Table t = reader_.read(skin.inverseBindMatrices, {TINYGLTF_TYPE_MAT4, {kFloat}},
                                   "skin 0 inverseBindMatrices");
      if (t.count < skin.joints.size())
        reader_.fail(fmt::format("skin 0 has {} joints but {} inverse bind matrices",
                                 skin.joints.size(), t.count));
      for (std::size_t i = 0; i < skin.joints.size(); ++i)
        for (int c = 0; c < 4; ++c)
          for (int r = 0; r < 4; ++r) inverse_binds[i](r, c) = t.at(i, c * 4 + r);
    }

    // Parent joint (as index in skin.joints, -1 for roots) of each skin joint.
    std::vector<int> parent_joint(skin.joints.size(), -1);
    std::vector<int> roots;
    for (std::size_t i = 0; i < skin.joints.size(); ++i) {
      for (int n = parent_[skin.joints[i]]; n >= 0 && parent_joint[i] < 0; n = parent_[n])
        if (auto it = skin_index.find(n); it != skin_index.end()) parent_joint[i] = it->second;
      if (parent_joint[i] < 0) roots.push_back(static_cast<int>(i));
    }

    std::vector<std::vector<int>> children(skin.joints.size());
    for (std::size_t i = 0; i < skin.joints.size(); ++i)
      if (parent_joint[i] >= 0) children[parent_joint[i]].push_back(static_cast<int>(i));
    auto add_subtree = [&](auto&& self, int i, int parent) -> void {
      joint_parents_.push_back(parent);
      const int here = static_cast<int>(joints_.size());
      joints_.push_back({skin.joints[i], i, inverse_binds[i]});
      for (int c : children[i]) self(self, c, here);
    };
    if (roots.size() == 1) {
      add_subtree(add_subtree, roots[0], -1);
    } else {
      SkinJoint root;
      root.node = common_ancestor(roots);
      if (root.node >= 0) root.inverse_bind = global(root.node, rest_).inverse();
      joints_.push_back(root);
      joint_parents_.push_back(-1);
      for (int r : roots) add_subtree(add_subtree, r, 0);
    }
    our_joint_.assign(skin.joints.size(), -1);
    for (std::size_t j = 0; j < joints_.size(); ++j)
      if (joints_[j].skin_index >= 0) our_joint_[joints_[j].skin_index] = static_cast<int>(j);
  }

  int common_ancestor(const std::vector<int>& roots) const {
    const std::vector<int>& joints = model_.skins[0].joints;
    for (int a = parent_[joints[roots[0]]]; a >= 0; a = parent_[a]) {
      bool all = true;
      for (int r : roots) {
        bool found = false;
        for (int n = parent_[joints[r]]; n >= 0 && !found; n = parent_[n]) found = n == a;
        all = all && found;
      }
      if (all) return a;
    }
    return -1;
  }

  std::string character_name() const {
    for (const tinygltf::Node& node : model_.nodes)
      if (node.skin == 0 && !node.name.empty()) return node.name;
    if (!model_.skins[0].name.empty()) return model_.skins[0].name;
    return fs::path(reader_.file()).stem().string();
  }

  // The bind pose is our rest pose: joint j rests at the origin of its bind frame, with its
  // frame turned to align with the world axes.
  void build_skeleton(Character& character) {
    Skeleton& skeleton = character.skeleton;
    std::set<std::string> used;
    rest_position_.resize(joints_.size());
    for (std::size_t j = 0; j < joints_.size(); ++j) {
      const SkinJoint& joint = joints_[j];
      std::string base = joint.node >= 0 ? model_.nodes[joint.node].name : "root";
      if (base.empty()) base = fmt::format("joint{}", joint.skin_index);
      std::string name = base;
      for (int k = 2; used.count(name); ++k) name = fmt::format("{}_{}", base, k);
      used.insert(name);
      const Eigen::Matrix4d bind = kOurFromGltf4 * joint.inverse_bind.inverse();
      rest_position_[j] = bind.topRightCorner<3, 1>();
      const int parent = joint_parents_[j];
      skeleton.names.push_back(name);
      skeleton.parents.push_back(parent);
      skeleton.rest_offsets.push_back(
          parent < 0 ? rest_position_[j]
                     : Eigen::Vector3d(rest_position_[j] - rest_position_[parent]));
      Eigen::Isometry3d inverse_bind = Eigen::Isometry3d::Identity();
      inverse_bind.translation() = -rest_position_[j];
      character.skin.inverse_bind.push_back(inverse_bind);
    }
  }

  // One tile of the texture: an image, or a flat colour.
  struct Tile {
    int image = -1;
    cv::Vec3b colour;  // BGR, when image < 0
    cv::Mat pixels;    // the tile's image (flat tiles: filled when packing)
    int x = 0, width = 0;
  };

  int tile_for(const tinygltf::Primitive& primitive, int* texcoord) {
    *texcoord = -1;
    int image = -1;
    std::vector<double> factor{1, 1, 1, 1};
    if (primitive.material >= 0 && primitive.material < static_cast<int>(model_.materials.size())) {
      const auto& pbr = model_.materials[primitive.material].pbrMetallicRoughness;
      if (pbr.baseColorFactor.size() == 4) factor = pbr.baseColorFactor;
      const int texture = pbr.baseColorTexture.index;
      if (texture >= 0 && texture < static_cast<int>(model_.textures.size())) {
        const int source = model_.textures[texture].source;
        if (source >= 0 && source < static_cast<int>(model_.images.size()) &&
            !model_.images[source].image.empty()) {
          image = source;
          *texcoord = pbr.baseColorTexture.texCoord;
        }
      }
    }
    Tile tile;
    tile.image = image;
    if (image < 0) {  // linear base colour factor -> sRGB texel
      for (int c = 0; c < 3; ++c) {
        const double v = std::clamp(factor[c], 0.0, 1.0);
        const double srgb = v <= 0.0031308 ? 12.92 * v : 1.055 * std::pow(v, 1 / 2.4) - 0.055;
        tile.colour[2 - c] = static_cast<unsigned char>(std::lround(255 * srgb));
      }
    }
    for (std::size_t i = 0; i < tiles_.size(); ++i)
      if (tiles_[i].image == tile.image && (image >= 0 || tiles_[i].colour == tile.colour))
        return static_cast<int>(i);
    tiles_.push_back(tile);
    return static_cast<int>(tiles_.size()) - 1;
  }

  // Triangle corner indices of a primitive (lists, strips and fans).
  std::vector<int> triangle_indices(const tinygltf::Primitive& p, std::size_t vertices,
                                    const std::string& what) {
    std::vector<int> idx;
    if (p.indices >= 0) {
      const Table t = reader_.read(p.indices, {TINYGLTF_TYPE_SCALAR, {kUByte, kUShort, kUInt}},
                                   what + " indices");
      for (double v : t.values) {
        // Checked before the conversion: an unsigned int index may not fit an int.
        if (!(v < static_cast<double>(vertices)))
          reader_.fail(fmt::format("{}: index {} out of range ({} vertices)", what, v, vertices));
        idx.push_back(static_cast<int>(v));
      }
    } else {
      idx.resize(vertices);
      std::iota(idx.begin(), idx.end(), 0);
    }
    for (int i : idx)
      if (i < 0 || static_cast<std::size_t>(i) >= vertices)
        reader_.fail(fmt::format("{}: index {} out of range ({} vertices)", what, i, vertices));
    std::vector<int> tris;
    const int mode = p.mode < 0 ? TINYGLTF_MODE_TRIANGLES : p.mode;
    if (mode == TINYGLTF_MODE_TRIANGLES) {
      tris.assign(idx.begin(), idx.begin() + idx.size() / 3 * 3);
    } else if (mode == TINYGLTF_MODE_TRIANGLE_STRIP) {
      for (std::size_t i = 2; i < idx.size(); ++i) {
        if (i % 2 == 0)
          tris.insert(tris.end(), {idx[i - 2], idx[i - 1], idx[i]});
        else
          tris.insert(tris.end(), {idx[i - 1], idx[i - 2], idx[i]});
      }
    } else if (mode == TINYGLTF_MODE_TRIANGLE_FAN) {
      for (std::size_t i = 2; i < idx.size(); ++i)
        tris.insert(tris.end(), {idx[0], idx[i - 1], idx[i]});
    }
    return tris;
  }

  void build_mesh(Character& character) {
    SkinnedMesh& skin = character.skin;
    Mesh& mesh = skin.rest;
    std::vector<int> vertex_tile;            // per vertex
    std::vector<Eigen::Vector2d> vertex_uv;  // per vertex, glTF convention, in its tile
    bool all_normals = true;
    int primitives = 0;
    for (std::size_t n = 0; n < model_.nodes.size(); ++n) {
      const tinygltf::Node& node = model_.nodes[n];
      if (node.skin != 0 || node.mesh < 0) continue;
      if (node.mesh >= static_cast<int>(model_.meshes.size()))
        reader_.fail(fmt::format("node {} references mesh {} which does not exist", n, node.mesh));
      const tinygltf::Mesh& m = model_.meshes[node.mesh];
      for (std::size_t pi = 0; pi < m.primitives.size(); ++pi) {
        const tinygltf::Primitive& p = m.primitives[pi];
        const int mode = p.mode < 0 ? TINYGLTF_MODE_TRIANGLES : p.mode;
        if (mode != TINYGLTF_MODE_TRIANGLES && mode != TINYGLTF_MODE_TRIANGLE_STRIP &&
            mode != TINYGLTF_MODE_TRIANGLE_FAN)
          continue;  // points and lines have no surface
        const std::string what = fmt::format("mesh '{}' primitive {}", m.name, pi);
        auto attribute = [&](const std::string& name) {
          auto it = p.attributes.find(name);
          return it == p.attributes.end() ? -1 : it->second;
        };
        if (attribute("POSITION") < 0) reader_.fail(what + ": no POSITION");
        if (attribute("JOINTS_0") < 0 || attribute("WEIGHTS_0") < 0)
          reader_.fail(what + ": no JOINTS_0/WEIGHTS_0 although its node is skinned");
        const Table pos =
            reader_.read(attribute("POSITION"), {TINYGLTF_TYPE_VEC3, {kFloat}}, what + " POSITION");
        const std::size_t count = pos.count;
        auto check_count = [&](const Table& t, const std::string& name) {
          if (t.count != count)
            reader_.fail(
                fmt::format("{} {}: {} elements for {} vertices", what, name, t.count, count));
        };
        const std::size_t first = mesh.positions.size();
        for (std::size_t i = 0; i < count; ++i)
          mesh.positions.push_back(
              (kOurFromGltf * Eigen::Vector3d(pos.at(i, 0), pos.at(i, 1), pos.at(i, 2)))
                  .cast<float>());
        if (attribute("NORMAL") >= 0 && all_normals) {
          const Table nrm =
              reader_.read(attribute("NORMAL"), {TINYGLTF_TYPE_VEC3, {kFloat}}, what + " NORMAL");
          check_count(nrm, "NORMAL");
          for (std::size_t i = 0; i < count; ++i)
            mesh.normals.push_back(
                (kOurFromGltf * Eigen::Vector3d(nrm.at(i, 0), nrm.at(i, 1), nrm.at(i, 2)))
                    .normalized()
                    .cast<float>());
        } else {
          all_normals = false;
        }
        int texcoord = -1;
        const int tile = tile_for(p, &texcoord);
        Table uv;
        if (texcoord >= 0) {
          const std::string name = fmt::format("TEXCOORD_{}", texcoord);
          if (attribute(name) < 0)
            reader_.fail(fmt::format("{}: its texture uses {} which it lacks", what, name));
          uv =
              reader_.read(attribute(name), {TINYGLTF_TYPE_VEC2, {kFloat, kUByteNorm, kUShortNorm}},
                           what + " " + name);
          check_count(uv, name);
        }
        for (std::size_t i = 0; i < count; ++i) {
          vertex_tile.push_back(tile);
          vertex_uv.push_back(texcoord >= 0 ? Eigen::Vector2d(uv.at(i, 0), uv.at(i, 1))
                                            : Eigen::Vector2d(0.5, 0.5));
        }
        read_weights(p, what, count, skin);
        const std::vector<int> tris = triangle_indices(p, count, what);
        for (std::size_t i = 0; i + 2 < tris.size(); i += 3)
          mesh.triangles.emplace_back(static_cast<int>(first) + tris[i],
                                      static_cast<int>(first) + tris[i + 1],
                                      static_cast<int>(first) + tris[i + 2]);
        ++primitives;
      }
    }
    if (primitives == 0) reader_.fail("no triangle mesh is bound to skin 0");
    if (!all_normals) {
      mesh.normals.clear();
      compute_vertex_normals(mesh);
    }
    pack_texture(character, vertex_tile, vertex_uv);
    Vec3f lo, hi;
    bounding_box(mesh, &lo, &hi);
    character.height = hi.z() - lo.z();
    mesh.check(reader_.file());
  }

  // Up to 8 influences (JOINTS_0/1, WEIGHTS_0/1) -> the 4 largest, renormalised.
  void read_weights(const tinygltf::Primitive& p, const std::string& what, std::size_t count,
                    SkinnedMesh& skin) {
    std::vector<std::vector<std::pair<double, int>>> influences(count);  // (weight, our joint)
    for (int set = 0;; ++set) {
      auto j_it = p.attributes.find(fmt::format("JOINTS_{}", set));
      auto w_it = p.attributes.find(fmt::format("WEIGHTS_{}", set));
      if (j_it == p.attributes.end() || w_it == p.attributes.end()) break;
      const Table j = reader_.read(j_it->second, {TINYGLTF_TYPE_VEC4, {kUByte, kUShort}},
                                   fmt::format("{} JOINTS_{}", what, set));
      const Table w =
          reader_.read(w_it->second, {TINYGLTF_TYPE_VEC4, {kFloat, kUByteNorm, kUShortNorm}},
                       fmt::format("{} WEIGHTS_{}", what, set));
      if (j.count != count || w.count != count)
        reader_.fail(fmt::format("{}: JOINTS_{}/WEIGHTS_{} do not have one element per vertex",
                                 what, set, set));
      for (std::size_t v = 0; v < count; ++v)
        for (int k = 0; k < 4; ++k) {
          if (w.at(v, k) <= 0) continue;
          const auto joint = static_cast<std::size_t>(j.at(v, k));
          if (joint >= our_joint_.size())
            reader_.fail(fmt::format("{}: vertex {} uses joint {} but the skin has {}", what, v,
                                     joint, our_joint_.size()));
          auto& list = influences[v];
          auto same = std::find_if(list.begin(), list.end(),
                                   [&](const auto& e) { return e.second == our_joint_[joint]; });
          if (same != list.end())
            same->first += w.at(v, k);
          else
            list.emplace_back(w.at(v, k), our_joint_[joint]);
        }
    }
    for (auto& list : influences) {
      std::sort(list.begin(), list.end(), std::greater<>());
      if (list.size() > 4) list.resize(4);
      double sum = 0;
      for (const auto& e : list) sum += e.first;
      Eigen::Vector4i joints = Eigen::Vector4i::Zero();
      Eigen::Vector4f weights = Eigen::Vector4f::Zero();
      if (sum <= 0) {
        weights[0] = 1;  // an unweighted vertex follows the root
      } else {
        for (std::size_t k = 0; k < list.size(); ++k) {
          joints[k] = list[k].second;
          weights[k] = static_cast<float>(list[k].first / sum);
        }
      }
      skin.joints.push_back(joints);
      skin.weights.push_back(weights);
    }
  }

  // One texture for the whole character: a single tile is used as is; several are resized to
  // one height and placed side by side, their UVs remapped (and clamped to the tile).
  void pack_texture(Character& character, const std::vector<int>& vertex_tile,
                    const std::vector<Eigen::Vector2d>& vertex_uv) {
    auto pixels = [&](int image) {
      const tinygltf::Image& im = model_.images[image];
      return cv::Mat(im.height, im.width, CV_8UC3, const_cast<unsigned char*>(im.image.data()))
          .clone();
    };
    auto& uvs = character.skin.rest.uvs;
    uvs.resize(vertex_uv.size());
    if (tiles_.size() == 1) {
      const Tile& tile = tiles_[0];
      character.texture =
          tile.image >= 0
              ? pixels(tile.image)
              : cv::Mat(8, 8, CV_8UC3, cv::Scalar(tile.colour[0], tile.colour[1], tile.colour[2]));
      for (std::size_t v = 0; v < uvs.size(); ++v)
        uvs[v] =
            Vec2f(static_cast<float>(vertex_uv[v].x()), static_cast<float>(1 - vertex_uv[v].y()));
      return;
    }
    constexpr int kMaxHeight = 2048, kMaxWidth = 8192, kFlatWidth = 8;
    int height = kFlatWidth;
    for (const Tile& t : tiles_)
      if (t.image >= 0) height = std::max(height, model_.images[t.image].height);
    double scale = std::min(1.0, static_cast<double>(kMaxHeight) / height);
    auto widths = [&](double s) {
      int total = 0;
      for (Tile& t : tiles_) {
        t.width = t.image < 0 ? kFlatWidth
                              : std::max(1, static_cast<int>(std::lround(
                                                s * height * model_.images[t.image].width /
                                                model_.images[t.image].height)));
        t.x = total;
        total += t.width;
      }
      return total;
    };
    int width = widths(scale);
    if (width > kMaxWidth) {
      scale *= static_cast<double>(kMaxWidth) / width;
      width = widths(scale);
    }
    height = std::max(1, static_cast<int>(std::lround(scale * height)));
    character.texture = cv::Mat(height, width, CV_8UC3);
    for (Tile& t : tiles_) {
      cv::Mat roi = character.texture(cv::Rect(t.x, 0, t.width, height));
      if (t.image < 0)
        roi.setTo(cv::Scalar(t.colour[0], t.colour[1], t.colour[2]));
      else
        cv::resize(pixels(t.image), roi, roi.size(), 0, 0, cv::INTER_AREA);
    }
    for (std::size_t v = 0; v < uvs.size(); ++v) {
      const Tile& t = tiles_[vertex_tile[v]];
      const double u = std::clamp(vertex_uv[v].x(), 0.0, 1.0);
      const double w = std::clamp(vertex_uv[v].y(), 0.0, 1.0);
      uvs[v] = Vec2f(static_cast<float>((t.x + u * t.width) / width), static_cast<float>(1 - w));
    }
  }

  // --- animation -----------------------------------------------------------------------------

  struct Channel {
    int node = -1;
    enum Path { kTranslation, kRotation, kScale } path = kRotation;
    enum Interpolation { kLinear, kStep, kCubic } interpolation = kLinear;
    std::vector<double> times;
    Table values;  // keys (cubic: in-tangent, value, out-tangent per key)
  };

  std::vector<Channel> read_channels(int a) {
    const tinygltf::Animation& animation = model_.animations[a];
    std::vector<Channel> channels;
    for (std::size_t c = 0; c < animation.channels.size(); ++c) {
      const tinygltf::AnimationChannel& ch = animation.channels[c];
      const std::string what = fmt::format("animation '{}' channel {}", animation.name, c);
      if (ch.target_path == "weights") continue;  // morph targets are not represented
      if (ch.target_node < 0 || ch.target_node >= static_cast<int>(model_.nodes.size()))
        reader_.fail(what + ": targets no node");
      if (ch.sampler < 0 || ch.sampler >= static_cast<int>(animation.samplers.size()))
        reader_.fail(what + ": no sampler");
      const tinygltf::AnimationSampler& s = animation.samplers[ch.sampler];
      Channel out;
      out.node = ch.target_node;
      if (ch.target_path == "translation")
        out.path = Channel::kTranslation;
      else if (ch.target_path == "rotation")
        out.path = Channel::kRotation;
      else if (ch.target_path == "scale")
        out.path = Channel::kScale;
      else
        reader_.fail(fmt::format("{}: unsupported target path '{}'", what, ch.target_path));
      if (s.interpolation == "LINEAR" || s.interpolation.empty())
        out.interpolation = Channel::kLinear;
      else if (s.interpolation == "STEP")
        out.interpolation = Channel::kStep;
      else if (s.interpolation == "CUBICSPLINE")
        out.interpolation = Channel::kCubic;
      else
        reader_.fail(fmt::format("{}: unsupported interpolation '{}'", what, s.interpolation));
      out.times = reader_.read(s.input, {TINYGLTF_TYPE_SCALAR, {kFloat}}, what + " input").values;
      if (out.path == Channel::kRotation)
        out.values = reader_.read(
            s.output,
            {TINYGLTF_TYPE_VEC4, {kFloat, kByteNorm, kUByteNorm, kShortNorm, kUShortNorm}},
            what + " rotation output");
      else
        out.values = reader_.read(s.output, {TINYGLTF_TYPE_VEC3, {kFloat}}, what + " output");
      const std::size_t per_key = out.interpolation == Channel::kCubic ? 3 : 1;
      if (out.times.empty() || out.values.count != per_key * out.times.size())
        reader_.fail(fmt::format("{}: {} keys but {} output values", what, out.times.size(),
                                 out.values.count));
      for (std::size_t k = 1; k < out.times.size(); ++k)
        if (!(out.times[k] > out.times[k - 1]))
          reader_.fail(fmt::format("{}: key times are not increasing at key {}", what, k));
      channels.push_back(std::move(out));
    }
    return channels;
  }

  // The channel's value at time t (4 components for rotations as x, y, z, w; else 3).
  static Eigen::Vector4d sample(const Channel& ch, double t) {
    const int comps = ch.values.components;
    const std::size_t keys = ch.times.size();
    const std::size_t stride = ch.interpolation == Channel::kCubic ? 3 : 1;
    const std::size_t offset = ch.interpolation == Channel::kCubic ? 1 : 0;  // the value
    auto key = [&](std::size_t k, std::size_t part) {
      Eigen::Vector4d v = Eigen::Vector4d::Zero();
      for (int c = 0; c < comps; ++c) v[c] = ch.values.at(k * stride + part, c);
      return v;
    };
    if (t <= ch.times.front()) return key(0, offset);
    if (t >= ch.times.back()) return key(keys - 1, offset);
    const std::size_t k =
        std::upper_bound(ch.times.begin(), ch.times.end(), t) - ch.times.begin() - 1;
    const double dt = ch.times[k + 1] - ch.times[k];
    const double u = (t - ch.times[k]) / dt;
    Eigen::Vector4d v;
    switch (ch.interpolation) {
      case Channel::kStep:
        return key(k, 0);
      case Channel::kCubic: {
        const double u2 = u * u, u3 = u2 * u;
        v = (2 * u3 - 3 * u2 + 1) * key(k, 1) + (u3 - 2 * u2 + u) * dt * key(k, 2) +
            (-2 * u3 + 3 * u2) * key(k + 1, 1) + (u3 - u2) * dt * key(k + 1, 0);
        break;
      }
      case Channel::kLinear:
        if (ch.path == Channel::kRotation) {
          const Eigen::Vector4d a = key(k, 0), b = key(k + 1, 0);
          const Eigen::Quaterniond qa(a[3], a[0], a[1], a[2]), qb(b[3], b[0], b[1], b[2]);
          const Eigen::Quaterniond q = qa.normalized().slerp(u, qb.normalized());
          return {q.x(), q.y(), q.z(), q.w()};
        }
        v = (1 - u) * key(k, 0) + u * key(k + 1, 0);
        break;
    }
    return v;
  }

  // The animation's own key rate: the median key spacing, snapped to a whole rate when close.
  static double key_rate(const std::vector<Channel>& channels) {
    std::vector<double> spacing;
    for (const Channel& ch : channels)
      for (std::size_t k = 1; k < ch.times.size(); ++k)
        spacing.push_back(ch.times[k] - ch.times[k - 1]);
    if (spacing.empty()) return 30;
    std::nth_element(spacing.begin(), spacing.begin() + spacing.size() / 2, spacing.end());
    const double fps = 1 / spacing[spacing.size() / 2];
    return std::abs(fps - std::round(fps)) < 1e-3 * fps ? std::round(fps) : fps;
  }

  MotionClip sample_animation(int a, const std::string& take, const Skeleton& skeleton) {
    const std::vector<Channel> channels = read_channels(a);
    double t0 = 0, t1 = 0;
    if (!channels.empty()) {
      t0 = std::numeric_limits<double>::infinity();
      t1 = -t0;
      for (const Channel& ch : channels) {
        t0 = std::min(t0, ch.times.front());
        t1 = std::max(t1, ch.times.back());
      }
    }
    const double fps = options_.fps > 0 ? options_.fps : key_rate(channels);
    // A take of a studio session is minutes long; a longer clip is a broken file (key times
    // or spacing), and its frame count would not even fit an int.
    constexpr double kMaxFrames = 1e6;
    const double span = (t1 - t0) * fps;
    if (!(span >= 0 && span < kMaxFrames)) {
      reader_.fail(fmt::format("animation {} ('{}') spans {} s of keys at {} frames per second, "
                               "more than {:.0f} frames",
                               a, take, t1 - t0, fps, kMaxFrames));
    }
    // A small tolerance so a key stored as float at the last frame time still counts.
    const int frames = static_cast<int>(std::floor(span + 1e-3)) + 1;
    std::vector<Pose> poses(frames);
    std::vector<Trs> local;
    std::vector<Eigen::Matrix3d> rotation(joints_.size());
    for (int f = 0; f < frames; ++f) {
      const double t = t0 + f / fps;
      local = rest_;
      for (const Channel& ch : channels) {
        const Eigen::Vector4d v = sample(ch, t);
        Trs& trs = local[ch.node];
        if (ch.path == Channel::kTranslation)
          trs.t = v.head<3>();
        else if (ch.path == Channel::kScale)
          trs.s = v.head<3>();
        else
          trs.r = Eigen::Quaterniond(v[3], v[0], v[1], v[2]).normalized();
      }
      Pose& pose = poses[f];
      pose.local_rotations.resize(joints_.size());
      for (std::size_t j = 0; j < joints_.size(); ++j) {
        // The skinning transform of joint j in our axes, times the rest frame of the joint,
        // is the joint's world frame at time t (up to the scale it cancels).
        const SkinJoint& joint = joints_[j];
        const Eigen::Matrix4d g =
            joint.node >= 0 ? global(joint.node, local) : Eigen::Matrix4d::Identity();
        Eigen::Matrix4d rest_frame = Eigen::Matrix4d::Identity();
        rest_frame.topRightCorner<3, 1>() = rest_position_[j];
        const Eigen::Matrix4d world =
            kOurFromGltf4 * g * joint.inverse_bind * kGltfFromOur4 * rest_frame;
        rotation[j] = nearest_rotation(world.topLeftCorner<3, 3>());
        const int parent = skeleton.parents[j];
        const Eigen::Matrix3d relative =
            parent < 0 ? rotation[j] : Eigen::Matrix3d(rotation[parent].transpose() * rotation[j]);
        pose.local_rotations[j] = Eigen::Quaterniond(relative).normalized();
        if (j == 0) pose.root_position = world.topRightCorner<3, 1>();
      }
    }
    return make_imported_clip(take, std::move(poses), fps);
  }

  GltfReader reader_;
  const tinygltf::Model& model_;
  GltfImportOptions options_;
  std::vector<int> parent_;        // per node, -1 for scene roots
  std::vector<Trs> rest_;          // per node, its own (unanimated) transform
  std::vector<SkinJoint> joints_;  // our joint order
  std::vector<int> joint_parents_;
  std::vector<int> our_joint_;                  // skin.joints index -> our joint
  std::vector<Eigen::Vector3d> rest_position_;  // per joint, bind position in our world
  std::vector<Tile> tiles_;
};

}  // namespace

void write_gltf_character(const fs::path& path, const Character& character,
                          const std::vector<MotionClip>& clips) {
  const std::string file = path.string();
  check_character(file, character, clips);
  tinygltf::Model model;
  model.asset.version = "2.0";
  model.asset.generator = "fourd synthetic studio";
  BufferWriter buffer(model);
  add_skeleton(model, buffer, character);
  add_mesh(model, buffer, character);
  for (const MotionClip& clip : clips) add_animation(model, buffer, clip);

  gltf::write_glb(path, model);
}

ImportedCharacter read_gltf_character(const fs::path& path, const GltfImportOptions& options) {
  const std::string file = path.string();
  const tinygltf::Model model = gltf::read_gltf(path);
  return CharacterImporter(file, model, options).run();
}

}  // namespace fourd::synth
