#include "runtime/gltf_export.h"

#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <map>
#include <set>

#include "pipeline/core/error.h"
#include "pipeline/gltf/gltf.h"

namespace fourd {
namespace {

// #V points out of planes x | y | z of `stride` floats each.
std::vector<Vec3f> points_from_planes(const float* planes, int stride, int count) {
  std::vector<Vec3f> points(count);
  for (int v = 0; v < count; ++v)
    points[v] = {planes[v], planes[stride + v], planes[2 * static_cast<std::size_t>(stride) + v]};
  return points;
}

// Unit length, as glTF requires of NORMAL (a degenerate normal points up).
Vec3f unit_normal(const Vec3f& n) {
  const float length = n.norm();
  return length > 1e-12f ? Vec3f(n / length) : Vec3f(0, 0, 1);
}

void check_animation(const std::string& file, const MeshAnimation& animation) {
  const Mesh& base = animation.base;
  const std::size_t vertices = base.num_vertices();
  if (base.empty())
    throw InputError(fmt::format("{}: the template mesh of '{}' is empty", file, animation.name));
  base.check(file + ": template");
  if (base.normals.size() != vertices)
    throw InputError(fmt::format("{}: the template has {} normals for {} vertices", file,
                                 base.normals.size(), vertices));
  std::set<std::string> names;
  for (const MeshClip& clip : animation.clips) {
    if (clip.name.empty()) throw InputError(fmt::format("{}: a clip has no name", file));
    if (!names.insert(clip.name).second)
      throw InputError(fmt::format("{}: two clips are named '{}'", file, clip.name));
    const std::size_t frames = clip.times.size();
    if (frames == 0) throw InputError(fmt::format("{}: clip '{}' has no frames", file, clip.name));
    if (clip.positions.size() != frames || clip.normals.size() != frames ||
        clip.roots.size() != frames)
      throw InputError(fmt::format(
          "{}: clip '{}' has {} times, {} position frames, {} normal frames, {} roots", file,
          clip.name, frames, clip.positions.size(), clip.normals.size(), clip.roots.size()));
    for (std::size_t f = 0; f < frames; ++f) {
      if (clip.positions[f].size() != vertices || clip.normals[f].size() != vertices)
        throw InputError(fmt::format("{}: clip '{}' frame {} has {} positions and {} normals, not {}",
                                     file, clip.name, f, clip.positions[f].size(),
                                     clip.normals[f].size(), vertices));
      if (!std::isfinite(clip.times[f]) || (f > 0 && !(clip.times[f] > clip.times[f - 1])))
        throw InputError(fmt::format("{}: clip '{}' frame {}: time {} does not increase", file,
                                     clip.name, f, clip.times[f]));
    }
  }
}

void add_float3(std::vector<float>* out, const Eigen::Vector3f& v) {
  out->insert(out->end(), {v.x(), v.y(), v.z()});
}

// The texture as the options ask: the PNG as given, or resized and re-encoded.
std::vector<unsigned char> texture_bytes(const std::string& file,
                                         const std::vector<unsigned char>& png,
                                         const TextureEncoding& encoding) {
  if (encoding.keeps_png()) return png;
  const cv::Mat image = cv::imdecode(png, cv::IMREAD_COLOR);
  if (image.empty()) throw InputError(fmt::format("{}: the texture is not a readable image", file));
  return encode_texture(image, encoding);
}

// The position grid of a compressed export (glTF axes): the template's positions as floats
// (p - centre) / step, every frame's displacements rounded to 16-bit integers on the grid.
struct PositionGrid {
  Eigen::Vector3f centre = Eigen::Vector3f::Zero();
  float step = 1;
};

PositionGrid position_grid(const MeshAnimation& animation, const std::vector<int>& source,
                           double step_mm) {
  Eigen::Vector3f lo = Eigen::Vector3f::Constant(std::numeric_limits<float>::infinity());
  Eigen::Vector3f hi = -lo;
  for (const int v : source) {
    const Eigen::Vector3f p = gltf::to_gltf(animation.base.positions[v]);
    lo = lo.cwiseMin(p);
    hi = hi.cwiseMax(p);
  }
  PositionGrid grid;
  grid.centre = 0.5f * (lo + hi);
  float range = 0;
  for (const MeshClip& clip : animation.clips)
    for (const std::vector<Vec3f>& frame : clip.positions)
      for (const int v : source)
        range = std::max(range, (frame[v] - animation.base.positions[v]).cwiseAbs().maxCoeff());
  grid.step = std::max(static_cast<float>(step_mm * 1e-3), range / 32767.0f);
  return grid;
}

std::int16_t grid_int(float value, float step) {
  return static_cast<std::int16_t>(std::clamp(std::lround(value / step), -32767L, 32767L));
}

std::int8_t normal_int(float value) {
  return static_cast<std::int8_t>(std::lround(127 * std::clamp(value, -1.0f, 1.0f)));
}

// Points (padded to 8 bytes) on the grid, relative to `origin`.
std::vector<std::int16_t> grid_positions(const std::vector<Eigen::Vector3f>& points,
                                         const Eigen::Vector3f& origin, float step) {
  std::vector<std::int16_t> q;
  q.reserve(4 * points.size());
  for (const Eigen::Vector3f& p : points) {
    const Eigen::Vector3f d = p - origin;
    q.insert(q.end(), {grid_int(d.x(), step), grid_int(d.y(), step), grid_int(d.z(), step), 0});
  }
  return q;
}

// Normals (or displacements, clamped to [-1, 1]) as normalised bytes, padded to 4 bytes.
std::vector<std::int8_t> byte_normals(const std::vector<Eigen::Vector3f>& normals) {
  std::vector<std::int8_t> q;
  q.reserve(4 * normals.size());
  for (const Eigen::Vector3f& n : normals)
    q.insert(q.end(), {normal_int(n.x()), normal_int(n.y()), normal_int(n.z()), 0});
  return q;
}

constexpr int kArray = TINYGLTF_TARGET_ARRAY_BUFFER;

// The compressed template primitive: quantised POSITION (on `grid`), NORMAL, TEXCOORD_0 and
// the indices, every view meshopt-compressed.
tinygltf::Primitive add_quantised_primitive(gltf::BufferWriter& buffer, const Mesh& mesh,
                                            bool with_uvs, const gltf::ExportVertices& vertices,
                                            const PositionGrid& grid) {
  std::vector<Eigen::Vector3f> positions, normals;
  std::vector<std::uint16_t> uvs;
  for (std::size_t i = 0; i < vertices.source.size(); ++i) {
    const int v = vertices.source[i];
    positions.push_back(gltf::to_gltf(mesh.positions[v]));
    normals.push_back(gltf::to_gltf(mesh.normals[v]));
    if (with_uvs) {
      const Vec2f& uv = mesh.uvs[vertices.uv[i]];
      for (const float c : {uv.x(), 1.0f - uv.y()})
        uvs.push_back(static_cast<std::uint16_t>(std::lround(65535 * std::clamp(c, 0.0f, 1.0f))));
    }
  }
  const std::size_t n = vertices.source.size();
  tinygltf::Primitive primitive;
  primitive.mode = TINYGLTF_MODE_TRIANGLES;
  // The template in grid units but as floats: exact, so a decoded vertex's error is the
  // displacement's rounding alone (the template is 12 bytes a vertex once, the displacements 8
  // a vertex per frame).
  std::vector<float> grid_template;
  for (const Eigen::Vector3f& p : positions)
    add_float3(&grid_template, Eigen::Vector3f((p - grid.centre) / grid.step));
  primitive.attributes["POSITION"] = buffer.add_meshopt_accessor(
      grid_template, n, 12, TINYGLTF_COMPONENT_TYPE_FLOAT, TINYGLTF_TYPE_VEC3, kArray, false,
      true);
  primitive.attributes["NORMAL"] =
      buffer.add_meshopt_accessor(byte_normals(normals), n, 4, TINYGLTF_COMPONENT_TYPE_BYTE,
                                  TINYGLTF_TYPE_VEC3, kArray, true);
  if (with_uvs)
    primitive.attributes["TEXCOORD_0"] =
        buffer.add_meshopt_accessor(uvs, n, 4, TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT,
                                    TINYGLTF_TYPE_VEC2, kArray, true);
  const std::size_t count = 3 * vertices.triangles.size();
  if (n <= 65536) {
    std::vector<std::uint16_t> indices;
    for (const Tri& t : vertices.triangles)
      for (int c = 0; c < 3; ++c) indices.push_back(static_cast<std::uint16_t>(t[c]));
    primitive.indices = buffer.add_meshopt_accessor(
        indices, count, 2, TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT, TINYGLTF_TYPE_SCALAR,
        TINYGLTF_TARGET_ELEMENT_ARRAY_BUFFER, false, false, gltf::MeshoptMode::kTriangles);
  } else {
    std::vector<std::uint32_t> indices;
    for (const Tri& t : vertices.triangles)
      for (int c = 0; c < 3; ++c) indices.push_back(static_cast<std::uint32_t>(t[c]));
    primitive.indices = buffer.add_meshopt_accessor(
        indices, count, 4, TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT, TINYGLTF_TYPE_SCALAR,
        TINYGLTF_TARGET_ELEMENT_ARRAY_BUFFER, false, false, gltf::MeshoptMode::kTriangles);
  }
  return primitive;
}

}  // namespace

gltf::ExportVertices glb_vertices(const Mesh& base, const GlbOptions& options) {
  gltf::ExportVertices vertices = gltf::export_vertices(base);
  if (options.compress) gltf::order_for_compression(&vertices);
  return vertices;
}

std::string TextureEncoding::extension() const {
  return format == "jpeg" ? ".jpg" : format == "webp" ? ".webp" : ".png";
}

std::string TextureEncoding::mime_type() const {
  return format == "jpeg" ? "image/jpeg" : format == "webp" ? "image/webp" : "image/png";
}

void TextureEncoding::check() const {
  if (size < 0 || size > 16384)
    throw UsageError(fmt::format("--texture-size {}: must lie in [0, 16384]", size));
  if (format != "png" && format != "jpeg" && format != "webp")
    throw UsageError(fmt::format("--texture-format {}: expected png, jpeg or webp", format));
  if (quality < 1 || quality > 100)
    throw UsageError(fmt::format("--texture-quality {}: must lie in [1, 100]", quality));
}

std::vector<unsigned char> encode_texture(const cv::Mat& input, const TextureEncoding& encoding) {
  cv::Mat image = input;
  if (encoding.size > 0) {
    const double scale = static_cast<double>(encoding.size) / std::max(image.cols, image.rows);
    const cv::Size size(std::max(1, static_cast<int>(std::lround(image.cols * scale))),
                        std::max(1, static_cast<int>(std::lround(image.rows * scale))));
    cv::resize(image, image, size, 0, 0, scale < 1 ? cv::INTER_AREA : cv::INTER_LINEAR);
  }
  std::vector<int> params;
  if (encoding.format == "jpeg") params = {cv::IMWRITE_JPEG_QUALITY, encoding.quality};
  if (encoding.format == "webp") params = {cv::IMWRITE_WEBP_QUALITY, encoding.quality};
  std::vector<unsigned char> bytes;
  if (!cv::imencode(encoding.extension(), image, bytes, params))
    throw IoError(fmt::format("cannot encode a texture as {}", encoding.format));
  return bytes;
}

void GlbOptions::check() const {
  if (!(position_step_mm >= 0.001 && position_step_mm <= 10))
    throw UsageError(
        fmt::format("--position-step {} mm: must lie in [0.001, 10]", position_step_mm));
  texture.check();
}

Mesh asset_template(const Asset& asset) {
  if (asset.graph.spaces.empty()) throw InputError("the asset has no motion space");
  const GraphSpace& space = asset.graph.spaces.front();
  const BlendSpace& blend = space.motion.blend;
  Mesh mesh;
  mesh.triangles = space.motion.triangles;
  const float* frame = blend.frame(0, 0);
  mesh.positions = points_from_planes(frame, blend.plane_stride, blend.num_vertices);
  mesh.normals = points_from_planes(space.normals_for(frame), blend.plane_stride,
                                    blend.num_vertices);
  for (Vec3f& n : mesh.normals) n = unit_normal(n);
  const AssetTextures& textures = asset.graph.textures;
  if (!textures.empty()) {
    // The atlas stores one UV per triangle corner; corners with the same UV share one index, so
    // the export splits vertices only at chart seams.
    std::map<std::pair<float, float>, int> index;
    mesh.uv_triangles.resize(mesh.triangles.size());
    for (std::size_t f = 0; f < mesh.triangles.size(); ++f) {
      for (int c = 0; c < 3; ++c) {
        const Vec2f& uv = textures.corner_uvs[3 * f + c];
        const auto [it, added] = index.try_emplace({uv.x(), uv.y()}, static_cast<int>(mesh.uvs.size()));
        if (added) mesh.uvs.push_back(uv);
        mesh.uv_triangles[f][c] = it->second;
      }
    }
  }
  return mesh;
}

std::vector<unsigned char> asset_template_texture_png(const Asset& asset) {
  const AssetTextures& textures = asset.graph.textures;
  if (textures.empty() || asset.graph.spaces.empty()) return {};
  const GraphSpace& space = asset.graph.spaces.front();
  std::vector<float> w(space.num_inputs(), 0.0f);
  w[0] = 1.0f;
  TextureBlend blend;
  texture_blend_add(textures, 0, space.motion.cyclic, 0.0, w, 1.0f, &blend);
  cv::Mat image;
  blend_texture_image(textures, blend, &image);
  std::vector<unsigned char> png;
  if (!cv::imencode(".png", image, png)) throw IoError("cannot encode the template's texture as PNG");
  return png;
}

std::vector<MeshClip> asset_take_clips(const Asset& asset) {
  std::vector<MeshClip> clips;
  for (int space_index = 0; space_index < static_cast<int>(asset.graph.spaces.size());
       ++space_index) {
    const GraphSpace& space = asset.graph.spaces[space_index];
    const MotionSpace& motion = space.motion;
    const BlendSpace& blend = motion.blend;
    for (int i = 0; i < motion.num_inputs(); ++i) {
      MeshClip clip;
      clip.name = motion.takes[i];
      for (int f = 0; f < blend.num_frames; ++f) {
        const float* frame = blend.frame(i, f);
        clip.times.push_back(motion.time(i, f));
        clip.positions.push_back(
            points_from_planes(frame, blend.plane_stride, blend.num_vertices));
        clip.normals.push_back(
            points_from_planes(space.normals_for(frame), blend.plane_stride, blend.num_vertices));
        const RootPose& root = motion.root(i, f);
        clip.roots.push_back({root.x, root.y, root.heading});
        if (!asset.graph.textures.empty()) {
          // Take i alone at the sample's normalised time.
          std::vector<float> w(motion.num_inputs(), 0.0f);
          w[i] = 1.0f;
          TextureBlend texture;
          const double t =
              blend.num_frames > 1 ? static_cast<double>(f) / (blend.num_frames - 1) : 0.0;
          texture_blend_add(asset.graph.textures, space_index, motion.cyclic, t, w, 1.0f,
                            &texture);
          clip.textures.push_back(texture);
        }
      }
      clips.push_back(std::move(clip));
    }
  }
  return clips;
}

namespace {

// Keeps every played frame of the character as one frame of a clip.
struct ClipRecorder : FrameObserver {
  explicit ClipRecorder(MeshClip& clip) : clip(clip) {}
  void on_frame(int, double time, const Character& character) override {
    const CharacterFrame& out = character.frame();
    clip.times.push_back(static_cast<float>(time));
    clip.positions.push_back(points_from_planes(out.positions.data.data(),
                                                out.positions.plane_stride,
                                                out.positions.num_vertices));
    clip.normals.push_back(points_from_planes(out.normals.data.data(), out.normals.plane_stride,
                                              out.normals.num_vertices));
    clip.roots.push_back(out.root);
    if (!character.graph().textures.empty()) clip.textures.push_back(out.textures);
  }
  MeshClip& clip;
};

}  // namespace

MeshClip bake_control_script(const Asset& asset, const ControlScript& script,
                             PlayerOptions options, const std::string& name) {
  MeshClip clip;
  clip.name = name;
  ClipRecorder recorder(clip);
  options.observer = &recorder;
  run_player(asset, script, options);
  return clip;
}

namespace {

// The performer's material, with the animation's texture when it has one.
void add_material(tinygltf::Model& model, gltf::BufferWriter& buffer, const std::string& file,
                  const MeshAnimation& animation, const GlbOptions& options, bool textured) {
  tinygltf::Material material;
  material.name = "performer";
  material.pbrMetallicRoughness.metallicFactor = 0;
  material.pbrMetallicRoughness.roughnessFactor = 1;
  if (textured) {
    const std::string mime = options.texture.mime_type();
    const int texture = buffer.add_image_texture(
        texture_bytes(file, animation.texture_png, options.texture), mime, "texture");
    if (mime == "image/webp") {
      tinygltf::Texture& t = model.textures[texture];
      tinygltf::Value::Object webp;
      webp["source"] = tinygltf::Value(t.source);
      t.extensions["EXT_texture_webp"] = tinygltf::Value(std::move(webp));
      t.source = -1;
      model.extensionsUsed.push_back("EXT_texture_webp");
      model.extensionsRequired.push_back("EXT_texture_webp");
    }
    material.pbrMetallicRoughness.baseColorTexture.index = texture;
  }
  model.materials.push_back(material);
}

// One morph target per frame of every clip: its displacement from the template (`base`, with
// `base_normals` its unit normals), quantised on `grid` when compressing. Returns their names.
tinygltf::Value::Array add_morph_targets(gltf::BufferWriter& buffer, const MeshAnimation& animation,
                                         const std::vector<Vec3f>& base_normals,
                                         const gltf::ExportVertices& vertices,
                                         const PositionGrid& grid, bool compress,
                                         tinygltf::Primitive& primitive) {
  const Mesh& base = animation.base;
  tinygltf::Value::Array target_names;
  const std::size_t n = vertices.source.size();
  for (const MeshClip& clip : animation.clips) {
    for (int f = 0; f < clip.num_frames(); ++f) {
      std::map<std::string, int> target;
      constexpr int kFloat = TINYGLTF_COMPONENT_TYPE_FLOAT;
      if (compress) {
        std::vector<Eigen::Vector3f> dp, dn;
        dp.reserve(n);
        dn.reserve(n);
        for (const int v : vertices.source) {
          dp.push_back(gltf::to_gltf(Vec3f(clip.positions[f][v] - base.positions[v])));
          dn.push_back(gltf::to_gltf(Vec3f(unit_normal(clip.normals[f][v]) - base_normals[v])));
        }
        target["POSITION"] = buffer.add_meshopt_accessor(
            grid_positions(dp, Eigen::Vector3f::Zero(), grid.step), n, 8,
            TINYGLTF_COMPONENT_TYPE_SHORT, TINYGLTF_TYPE_VEC3, kArray, false, true);
        target["NORMAL"] = buffer.add_meshopt_accessor(
            byte_normals(dn), n, 4, TINYGLTF_COMPONENT_TYPE_BYTE, TINYGLTF_TYPE_VEC3, kArray, true);
      } else {
        std::vector<float> dp, dn;
        dp.reserve(3 * n);
        dn.reserve(3 * n);
        for (const int v : vertices.source) {
          add_float3(&dp, gltf::to_gltf(Vec3f(clip.positions[f][v] - base.positions[v])));
          add_float3(&dn, gltf::to_gltf(Vec3f(unit_normal(clip.normals[f][v]) - base_normals[v])));
        }
        target["POSITION"] = buffer.add_accessor(dp, kFloat, TINYGLTF_TYPE_VEC3, kArray, true);
        target["NORMAL"] = buffer.add_accessor(dn, kFloat, TINYGLTF_TYPE_VEC3, kArray);
      }
      primitive.targets.push_back(std::move(target));
      target_names.emplace_back(fmt::format("{}.{:04d}", clip.name, f));
    }
  }
  return target_names;
}

// The root motion animates node 0; the mesh hangs on it, or (compressed) on a static child
// node that dequantises the positions. Adds the scene too; returns the mesh's node.
int add_nodes(tinygltf::Model& model, const std::string& name, const PositionGrid& grid,
              bool compress) {
  tinygltf::Node node;
  node.name = name.empty() ? "character" : name;
  int mesh_node = 0;
  if (compress) {
    node.children = {1};
    model.nodes.push_back(node);
    tinygltf::Node quantised;
    quantised.name = node.name + "_mesh";
    quantised.mesh = 0;
    quantised.translation = {grid.centre.x(), grid.centre.y(), grid.centre.z()};
    quantised.scale = {grid.step, grid.step, grid.step};
    model.nodes.push_back(quantised);
    mesh_node = 1;
  } else {
    node.mesh = 0;
    model.nodes.push_back(node);
  }
  tinygltf::Scene scene;
  scene.name = node.name;
  scene.nodes = {0};
  model.scenes.push_back(scene);
  model.defaultScene = 0;
  return mesh_node;
}

// One animation per clip: one-hot weights over the `num_targets` morph targets, the root's
// translation and heading.
void add_clip_animations(tinygltf::Model& model, gltf::BufferWriter& buffer,
                         const MeshAnimation& animation, std::size_t num_targets, int mesh_node,
                         bool compress) {
  std::size_t first_target = 0;
  for (const MeshClip& clip : animation.clips) {
    const int frames = clip.num_frames();
    tinygltf::Animation anim;
    anim.name = clip.name;
    const int input =
        compress ? buffer.add_meshopt_accessor(clip.times, clip.times.size(), sizeof(float),
                                               TINYGLTF_COMPONENT_TYPE_FLOAT, TINYGLTF_TYPE_SCALAR,
                                               0, false, /*with_bounds=*/true)
                 : buffer.add_accessor(clip.times, TINYGLTF_COMPONENT_TYPE_FLOAT,
                                       TINYGLTF_TYPE_SCALAR, 0, /*with_bounds=*/true);
    std::vector<float> weights(static_cast<std::size_t>(frames) * num_targets, 0.0f);
    for (int f = 0; f < frames; ++f) weights[f * num_targets + first_target + f] = 1;
    gltf::add_linear_channel(&anim, buffer, input, mesh_node, "weights", weights,
                             TINYGLTF_TYPE_SCALAR, compress);
    std::vector<float> translations;
    std::vector<Eigen::Quaterniond> rotations;
    for (const RootTransform& root : clip.roots) {
      add_float3(&translations, gltf::to_gltf(Vec3f(static_cast<float>(root.x),
                                                    static_cast<float>(root.y), 0.0f)));
      rotations.emplace_back(Eigen::AngleAxisd(root.heading, Eigen::Vector3d::UnitZ()));
    }
    gltf::add_linear_channel(&anim, buffer, input, 0, "translation", translations,
                             TINYGLTF_TYPE_VEC3, compress);
    gltf::add_linear_channel(&anim, buffer, input, 0, "rotation", gltf::rotation_keys(rotations),
                             TINYGLTF_TYPE_VEC4, compress);
    model.animations.push_back(std::move(anim));
    first_target += frames;
  }
}

}  // namespace

void write_mesh_animation_glb(const std::filesystem::path& path, const MeshAnimation& animation,
                              const GlbOptions& options) {
  const std::string file = path.string();
  options.check();
  check_animation(file, animation);
  const Mesh& base = animation.base;
  const bool textured = !base.uvs.empty() && !animation.texture_png.empty();
  const bool compress = options.compress;

  tinygltf::Model model;
  model.asset.version = "2.0";
  model.asset.generator = "fourd-export";
  gltf::BufferWriter buffer(model);

  // The template, with unit normals (glTF requires them).
  Mesh unit_base = base;
  for (Vec3f& n : unit_base.normals) n = unit_normal(n);
  gltf::ExportVertices vertices;
  tinygltf::Primitive primitive;
  PositionGrid grid;
  if (compress) {
    vertices = glb_vertices(unit_base, options);
    grid = position_grid(animation, vertices.source, options.position_step_mm);
    primitive = add_quantised_primitive(buffer, unit_base, textured, vertices, grid);
    model.extensionsUsed.push_back("KHR_mesh_quantization");
    model.extensionsRequired.push_back("KHR_mesh_quantization");
  } else {
    primitive = gltf::add_mesh_primitive(buffer, unit_base, textured, &vertices);
  }
  add_material(model, buffer, file, animation, options, textured);
  primitive.material = 0;
  tinygltf::Value::Array target_names =
      add_morph_targets(buffer, animation, unit_base.normals, vertices, grid, compress, primitive);
  const std::size_t num_targets = primitive.targets.size();

  tinygltf::Mesh mesh;
  mesh.name = animation.name;
  mesh.primitives.push_back(std::move(primitive));
  mesh.weights.assign(num_targets, 0.0);
  // Shape key names for Blender and three.js (the convention both read).
  tinygltf::Value::Object extras;
  extras["targetNames"] = tinygltf::Value(std::move(target_names));
  mesh.extras = tinygltf::Value(std::move(extras));
  model.meshes.push_back(std::move(mesh));

  const int mesh_node = add_nodes(model, animation.name, grid, compress);
  add_clip_animations(model, buffer, animation, num_targets, mesh_node, compress);
  gltf::write_glb(path, model, buffer.meshopt_views());
}

}  // namespace fourd
