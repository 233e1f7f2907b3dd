#include "runtime/gltf_export.h"

#include <opencv2/imgcodecs.hpp>

#include <fmt/format.h>

#include <cmath>
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

}  // namespace

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
  for (const GraphSpace& space : asset.graph.spaces) {
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

void write_mesh_animation_glb(const std::filesystem::path& path, const MeshAnimation& animation) {
  const std::string file = path.string();
  check_animation(file, animation);
  const Mesh& base = animation.base;
  const bool textured = !base.uvs.empty() && !animation.texture_png.empty();

  tinygltf::Model model;
  model.asset.version = "2.0";
  model.asset.generator = "fourd-export";
  gltf::BufferWriter buffer(model);

  // The template, with unit normals (glTF requires them).
  Mesh unit_base = base;
  for (Vec3f& n : unit_base.normals) n = unit_normal(n);
  const std::vector<Vec3f>& base_normals = unit_base.normals;
  gltf::ExportVertices vertices;
  tinygltf::Primitive primitive = gltf::add_mesh_primitive(buffer, unit_base, textured, &vertices);

  tinygltf::Material material;
  material.name = "performer";
  material.pbrMetallicRoughness.metallicFactor = 0;
  material.pbrMetallicRoughness.roughnessFactor = 1;
  if (textured)
    material.pbrMetallicRoughness.baseColorTexture.index =
        buffer.add_png_texture(animation.texture_png, "texture");
  model.materials.push_back(material);
  primitive.material = 0;

  // One morph target per frame of every clip: its displacement from the template.
  tinygltf::Value::Array target_names;
  for (const MeshClip& clip : animation.clips) {
    for (int f = 0; f < clip.num_frames(); ++f) {
      std::vector<float> dp, dn;
      dp.reserve(3 * vertices.source.size());
      dn.reserve(3 * vertices.source.size());
      for (const int v : vertices.source) {
        add_float3(&dp, gltf::to_gltf(Vec3f(clip.positions[f][v] - base.positions[v])));
        add_float3(&dn, gltf::to_gltf(Vec3f(unit_normal(clip.normals[f][v]) - base_normals[v])));
      }
      std::map<std::string, int> target;
      constexpr int kArray = TINYGLTF_TARGET_ARRAY_BUFFER;
      constexpr int kFloat = TINYGLTF_COMPONENT_TYPE_FLOAT;
      target["POSITION"] = buffer.add_accessor(dp, kFloat, TINYGLTF_TYPE_VEC3, kArray, true);
      target["NORMAL"] = buffer.add_accessor(dn, kFloat, TINYGLTF_TYPE_VEC3, kArray);
      primitive.targets.push_back(std::move(target));
      target_names.emplace_back(fmt::format("{}.{:04d}", clip.name, f));
    }
  }
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

  tinygltf::Node node;
  node.name = animation.name.empty() ? "character" : animation.name;
  node.mesh = 0;
  model.nodes.push_back(node);
  tinygltf::Scene scene;
  scene.name = node.name;
  scene.nodes = {0};
  model.scenes.push_back(scene);
  model.defaultScene = 0;

  // One animation per clip: one-hot weights, the root's translation and heading.
  std::size_t first_target = 0;
  for (const MeshClip& clip : animation.clips) {
    const int frames = clip.num_frames();
    tinygltf::Animation anim;
    anim.name = clip.name;
    const int input =
        buffer.add_accessor(clip.times, TINYGLTF_COMPONENT_TYPE_FLOAT, TINYGLTF_TYPE_SCALAR, 0,
                            /*with_bounds=*/true);
    std::vector<float> weights(static_cast<std::size_t>(frames) * num_targets, 0.0f);
    for (int f = 0; f < frames; ++f) weights[f * num_targets + first_target + f] = 1;
    gltf::add_linear_channel(&anim, buffer, input, 0, "weights", weights, TINYGLTF_TYPE_SCALAR);
    std::vector<float> translations;
    std::vector<Eigen::Quaterniond> rotations;
    for (const RootTransform& root : clip.roots) {
      add_float3(&translations, gltf::to_gltf(Vec3f(static_cast<float>(root.x),
                                                    static_cast<float>(root.y), 0.0f)));
      rotations.emplace_back(Eigen::AngleAxisd(root.heading, Eigen::Vector3d::UnitZ()));
    }
    gltf::add_linear_channel(&anim, buffer, input, 0, "translation", translations,
                             TINYGLTF_TYPE_VEC3);
    gltf::add_linear_channel(&anim, buffer, input, 0, "rotation", gltf::rotation_keys(rotations),
                             TINYGLTF_TYPE_VEC4);
    model.animations.push_back(std::move(anim));
    first_target += frames;
  }
  gltf::write_glb(path, model);
}

}  // namespace fourd
