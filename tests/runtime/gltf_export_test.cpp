#include "runtime/gltf_export.h"

#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <nlohmann/json.hpp>
#include <cstring>
#include <filesystem>
#include <opencv2/imgcodecs.hpp>

#include "pipeline/core/error.h"
#include "pipeline/core/files.h"
#include "pipeline/core/mesh_io.h"
#include "pipeline/core/se2.h"
#include "pipeline/gltf/gltf.h"
#include "runtime/mesh_sequence.h"
#include "tests/graph/test_graph.h"
#include "tests/scratch_dir.h"

namespace fourd {
namespace {

namespace fs = std::filesystem;

const Asset& test_asset() {
  static const Asset asset = [] {
    Asset a;
    a.graph = test::make_test_graph(true);
    return a;
  }();
  return asset;
}

MeshAnimation takes_of(const Asset& asset) {
  MeshAnimation animation;
  animation.name = asset.graph.name;
  animation.base = asset_template(asset);
  animation.clips = asset_take_clips(asset);
  return animation;
}

// The floats of a tightly packed float accessor.
std::vector<float> floats(const tinygltf::Model& model, int accessor_index) {
  const tinygltf::Accessor& a = model.accessors.at(accessor_index);
  EXPECT_EQ(a.componentType, TINYGLTF_COMPONENT_TYPE_FLOAT);
  const tinygltf::BufferView& view = model.bufferViews.at(a.bufferView);
  const std::size_t n = a.count * tinygltf::GetNumComponentsInType(a.type);
  std::vector<float> out(n);
  std::memcpy(out.data(), model.buffers.at(view.buffer).data.data() + view.byteOffset + a.byteOffset,
              n * sizeof(float));
  return out;
}

Vec3f our_point(const std::vector<float>& values, std::size_t i) {
  return (gltf::kOurFromGltf.cast<float>() *
          Eigen::Vector3f(values[3 * i], values[3 * i + 1], values[3 * i + 2]))
      .eval();
}

// The sampler output of `animation`'s channel on `path`.
std::vector<float> channel_output(const tinygltf::Model& model, const tinygltf::Animation& anim,
                                  const std::string& path) {
  for (const tinygltf::AnimationChannel& c : anim.channels)
    if (c.target_path == path) return floats(model, anim.samplers.at(c.sampler).output);
  ADD_FAILURE() << "no " << path << " channel in " << anim.name;
  return {};
}

TEST(GltfExport, EveryTakeIsAClipOfMorphTargetsWithTheRootOnTheNode) {
  const Asset& asset = test_asset();
  const fs::path file = test::scratch_dir("takes") / "character.glb";
  write_mesh_animation_glb(file, takes_of(asset));
  const tinygltf::Model model = gltf::read_gltf(file);

  const int vertices = asset.graph.num_vertices();
  ASSERT_EQ(model.meshes.size(), 1u);
  const tinygltf::Primitive& primitive = model.meshes[0].primitives.at(0);
  EXPECT_EQ(model.accessors.at(primitive.attributes.at("POSITION")).count, vertices);
  EXPECT_EQ(primitive.attributes.count("TEXCOORD_0"), 0u);  // the asset has no UVs
  std::vector<std::string> takes;
  std::size_t frames = 0;
  for (const GraphSpace& s : asset.graph.spaces) {
    takes.insert(takes.end(), s.motion.takes.begin(), s.motion.takes.end());
    frames += static_cast<std::size_t>(s.num_inputs()) * s.num_samples();
  }
  EXPECT_EQ(primitive.targets.size(), frames);
  EXPECT_EQ(model.meshes[0].weights.size(), frames);
  ASSERT_EQ(model.animations.size(), takes.size());
  for (std::size_t k = 0; k < takes.size(); ++k) EXPECT_EQ(model.animations[k].name, takes[k]);

  // The turning space's last input (it turns): template + target = the asset's frame, the keys
  // are its capture times, one-hot weights, and the node carries its root.
  const int space_index = asset.graph.find_space("turning");
  ASSERT_GE(space_index, 0);
  const MotionSpace& space = asset.graph.spaces[space_index].motion;
  const int input = space.num_inputs() - 1;
  std::size_t first_target = 0;
  for (int s = 0; s < space_index; ++s)
    first_target += static_cast<std::size_t>(asset.graph.spaces[s].num_inputs()) *
                    asset.graph.spaces[s].num_samples();
  first_target += static_cast<std::size_t>(input) * space.num_samples();
  const tinygltf::Animation* anim = nullptr;
  for (const tinygltf::Animation& a : model.animations)
    if (a.name == space.takes[input]) anim = &a;
  ASSERT_NE(anim, nullptr);
  const std::vector<float> base = floats(model, primitive.attributes.at("POSITION"));
  const std::vector<float> times = floats(model, anim->samplers.at(0).input);
  const std::vector<float> weights = channel_output(model, *anim, "weights");
  const std::vector<float> translation = channel_output(model, *anim, "translation");
  const std::vector<float> rotation = channel_output(model, *anim, "rotation");
  const int samples = space.num_samples();
  ASSERT_EQ(times.size(), static_cast<std::size_t>(samples));
  ASSERT_EQ(weights.size(), samples * frames);
  double max_error = 0;
  for (const int f : {0, samples / 2, samples - 1}) {
    EXPECT_FLOAT_EQ(times[f], space.time(input, f));
    for (std::size_t t = 0; t < frames; ++t)
      EXPECT_EQ(weights[f * frames + t], t == first_target + f ? 1.0f : 0.0f);
    const std::vector<float> delta =
        floats(model, primitive.targets.at(first_target + f).at("POSITION"));
    const float* expected = space.blend.frame(input, f);
    for (int v = 0; v < vertices; ++v) {
      const Vec3f p = our_point(base, v) + our_point(delta, v);
      const Vec3f e(expected[v], expected[space.blend.plane_stride + v],
                    expected[2 * space.blend.plane_stride + v]);
      max_error = std::max(max_error, static_cast<double>((p - e).norm()));
    }
    const RootPose& root = space.root(input, f);
    EXPECT_LT((our_point(translation, f) - Vec3f(root.x, root.y, 0)).norm(), 1e-5f) << f;
    const Eigen::Quaterniond q(rotation[4 * f + 3], rotation[4 * f], rotation[4 * f + 1],
                               rotation[4 * f + 2]);
    // glTF +y is our up: the node turns about it by the root's heading.
    const Eigen::Vector3d forward =
        gltf::kOurFromGltf * (q * (gltf::kOurFromGltf.transpose() * Eigen::Vector3d::UnitX()));
    EXPECT_NEAR(std::atan2(forward.y(), forward.x()), wrap_heading(root.heading), 1e-5);
  }
  EXPECT_LT(max_error, 1e-5);
  EXPECT_GT(std::abs(space.root(input, samples - 1).heading), 0.1);  // the check saw a turn
}

TEST(GltfExport, WritesUVsSplitAtSeamsAndTheTextureWhenTheTemplateHasThem) {
  const Asset& asset = test_asset();
  MeshAnimation animation = takes_of(asset);
  animation.clips.resize(1);
  Mesh& base = animation.base;
  // Per-corner UVs, each corner its own: every triangle becomes a UV island.
  for (std::size_t f = 0; f < base.num_triangles(); ++f) {
    const int k = static_cast<int>(base.uvs.size());
    base.uv_triangles.push_back(Tri(k, k + 1, k + 2));
    const float u = static_cast<float>(f) / base.num_triangles();
    base.uvs.insert(base.uvs.end(), {Vec2f(u, 0.1f), Vec2f(u, 0.9f), Vec2f(u + 1e-3f, 0.5f)});
  }
  cv::Mat image(8, 16, CV_8UC3, cv::Scalar(20, 120, 220));
  ASSERT_TRUE(cv::imencode(".png", image, animation.texture_png));
  const fs::path file = test::scratch_dir("uv") / "textured.glb";
  write_mesh_animation_glb(file, animation);
  const tinygltf::Model model = gltf::read_gltf(file);
  const tinygltf::Primitive& primitive = model.meshes.at(0).primitives.at(0);
  const std::size_t corners = 3 * base.num_triangles();
  EXPECT_EQ(model.accessors.at(primitive.attributes.at("POSITION")).count, corners);
  const std::vector<float> uvs = floats(model, primitive.attributes.at("TEXCOORD_0"));
  ASSERT_EQ(uvs.size(), 2 * corners);
  EXPECT_FLOAT_EQ(uvs[1], 0.9f);  // v counts from the top in glTF
  ASSERT_EQ(model.materials.size(), 1u);
  const int texture = model.materials[0].pbrMetallicRoughness.baseColorTexture.index;
  ASSERT_GE(texture, 0);
  const tinygltf::Image& decoded = model.images.at(model.textures.at(texture).source);
  EXPECT_EQ(decoded.width, 16);
  EXPECT_EQ(decoded.height, 8);
  // The split vertices move with their source vertex.
  const std::vector<float> positions = floats(model, primitive.attributes.at("POSITION"));
  const std::vector<float> delta = floats(model, primitive.targets.at(3).at("POSITION"));
  const MeshClip& clip = animation.clips[0];
  for (std::size_t c = 0; c < corners; c += 7) {
    const int v = base.triangles[c / 3][c % 3];
    EXPECT_TRUE((our_point(positions, c) + our_point(delta, c)).isApprox(clip.positions[3][v], 1e-5f));
  }
}

TEST(GltfExport, BakesAControlScriptAsOneMoreClip) {
  const Asset& asset = test_asset();
  const ControlScript script = parse_control_script(
      "fps 20\nduration 3\nstart locomotion 1.2\nat 1.0 motion jump_length 1.0\n", "jump.txt");
  const MeshClip clip = bake_control_script(asset, script, PlayerOptions{}, "jump");
  ASSERT_EQ(clip.num_frames(), 61);
  EXPECT_FLOAT_EQ(clip.times[20], 1.0f);
  EXPECT_GT(clip.roots.back().x, clip.roots.front().x + 0.5);  // it went forward
  MeshAnimation animation = takes_of(asset);
  const std::size_t takes = animation.clips.size();
  animation.clips.push_back(clip);
  const fs::path file = test::scratch_dir("script") / "script.glb";
  write_mesh_animation_glb(file, animation);
  const tinygltf::Model model = gltf::read_gltf(file);
  ASSERT_EQ(model.animations.size(), takes + 1);
  EXPECT_EQ(model.animations.back().name, "jump");
  const std::vector<float> translation = channel_output(model, model.animations.back(), "translation");
  const Vec3f last(static_cast<float>(clip.roots[60].x), static_cast<float>(clip.roots[60].y), 0);
  EXPECT_LT((our_point(translation, 60) - last).norm(), 1e-4f);
}

// The JSON chunk of a .glb.
nlohmann::json glb_json(const fs::path& file) {
  const std::string bytes = read_file(file);
  std::uint32_t length = 0;
  std::memcpy(&length, bytes.data() + 12, 4);
  return nlohmann::json::parse(bytes.substr(20, length));
}

TEST(GltfExport, CompressedDeclaresMeshoptAndQuantisationAndIsSmaller) {
  const Asset& asset = test_asset();
  const fs::path dir = test::scratch_dir("compressed");
  write_mesh_animation_glb(dir / "plain.glb", takes_of(asset));
  GlbOptions options;
  options.compress = true;
  write_mesh_animation_glb(dir / "packed.glb", takes_of(asset), options);
  EXPECT_LT(fs::file_size(dir / "packed.glb") * 2, fs::file_size(dir / "plain.glb"));
  const nlohmann::json j = glb_json(dir / "packed.glb");
  const std::vector<std::string> required = j.at("extensionsRequired");
  EXPECT_EQ(required, (std::vector<std::string>{"KHR_mesh_quantization", "EXT_meshopt_compression"}));
  // Buffer 1 is the fallback every compressed view points into; the codec's bytes are in 0.
  ASSERT_EQ(j.at("buffers").size(), 2u);
  EXPECT_TRUE(j["buffers"][1]["extensions"]["EXT_meshopt_compression"]["fallback"].get<bool>());
  for (const nlohmann::json& view : j.at("bufferViews")) {
    EXPECT_EQ(view.at("buffer"), 1);
    const nlohmann::json& ext = view.at("extensions").at("EXT_meshopt_compression");
    EXPECT_EQ(ext.at("buffer"), 0);
    EXPECT_EQ(view.at("byteLength").get<std::size_t>(),
              ext.at("count").get<std::size_t>() * ext.at("byteStride").get<std::size_t>());
    EXPECT_LT(ext.at("byteLength").get<std::size_t>(), view.at("byteLength").get<std::size_t>() + 64);
  }
  // The root motion on node 0, the mesh on its static child that dequantises the positions
  // (the test asset moves little: the grid step is the default 0.8 mm).
  const nlohmann::json& nodes = j.at("nodes");
  ASSERT_EQ(nodes.size(), 2u);
  EXPECT_EQ(nodes[0].at("children"), nlohmann::json::array({1}));
  EXPECT_FALSE(nodes[0].contains("mesh"));
  EXPECT_EQ(nodes[1].at("mesh"), 0);
  EXPECT_NEAR(nodes[1].at("scale")[0].get<double>(), 0.0008, 1e-9);
  for (const nlohmann::json& channel : j["animations"][0]["channels"])
    EXPECT_EQ(channel["target"]["node"], channel["target"]["path"] == "weights" ? 1 : 0);
  const nlohmann::json& primitive = j["meshes"][0]["primitives"][0];
  EXPECT_EQ(j["accessors"][primitive["attributes"]["POSITION"].get<int>()]["componentType"], 5126);
  EXPECT_EQ(j["accessors"][primitive["attributes"]["NORMAL"].get<int>()]["componentType"], 5120);
  EXPECT_EQ(j["accessors"][primitive["targets"][0]["POSITION"].get<int>()]["componentType"], 5122);
  // The vertices are reordered for the codec, still one per template vertex.
  const gltf::ExportVertices order = glb_vertices(asset_template(asset), options);
  std::vector<int> sorted = order.source;
  std::sort(sorted.begin(), sorted.end());
  for (std::size_t v = 0; v < sorted.size(); ++v) ASSERT_EQ(sorted[v], static_cast<int>(v));
}

TEST(GltfExport, RefusesBadTextureOptions) {
  GlbOptions options;
  options.texture.format = "gif";
  EXPECT_THROW(options.check(), UsageError);
  options.texture.format = "webp";
  options.texture.quality = 0;
  EXPECT_THROW(options.check(), UsageError);
  options.texture.quality = 80;
  options.position_step_mm = 0;
  EXPECT_THROW(options.check(), UsageError);
}

TEST(MeshSequence, WritesEveryFrameAndAManifestAsAWhole) {
  const Asset& asset = test_asset();
  const std::vector<MeshClip> clips = asset_take_clips(asset);
  const MeshClip& clip = clips.back();
  const fs::path dir = test::scratch_dir("sequence") / "seq";
  const SequenceReport report = write_mesh_sequence(dir, asset, clip, 25, SequenceOptions{});
  EXPECT_EQ(report.frames, clip.num_frames());
  const nlohmann::json manifest = nlohmann::json::parse(read_file(dir / "sequence.json"));
  EXPECT_EQ(manifest.at("clip"), clip.name);
  EXPECT_EQ(manifest.at("fps"), 25.0);
  ASSERT_EQ(manifest.at("frames").size(), static_cast<std::size_t>(clip.num_frames()));
  const int last = clip.num_frames() - 1;
  const nlohmann::json& frame = manifest["frames"][last];
  const Mesh mesh = read_mesh(dir / frame.at("mesh").get<std::string>());
  ASSERT_EQ(mesh.num_vertices(), clip.positions[last].size());
  // World coordinates: the root-frame vertex turned by the heading and moved by the root.
  const RootTransform& root = clip.roots[last];
  const Vec3f p = clip.positions[last][0];
  const Vec3f world(static_cast<float>(root.x + std::cos(root.heading) * p.x() -
                                       std::sin(root.heading) * p.y()),
                    static_cast<float>(root.y + std::sin(root.heading) * p.x() +
                                       std::cos(root.heading) * p.y()),
                    p.z());
  EXPECT_LT((mesh.positions[0] - world).norm(), 1e-5f);
  EXPECT_FLOAT_EQ(frame["bounding_box"]["max"][2].get<float>(),
                  std::max_element(mesh.positions.begin(), mesh.positions.end(),
                                   [](const Vec3f& a, const Vec3f& b) { return a.z() < b.z(); })
                      ->z());
  EXPECT_FALSE(frame.contains("texture"));  // the test asset has no textures

  // A clip that does not fit the asset is refused and the folder stays as it was.
  MeshClip bad = clip;
  bad.positions.back().pop_back();
  EXPECT_THROW(write_mesh_sequence(dir, asset, bad, 25, SequenceOptions{}), InputError);
  EXPECT_EQ(nlohmann::json::parse(read_file(dir / "sequence.json")), manifest);
  for (const auto& entry : fs::directory_iterator(dir.parent_path()))
    EXPECT_EQ(entry.path().filename(), "seq");  // no staging folder left
}

TEST(GltfExport, RefusesInconsistentClipsAndUnwritablePaths) {
  const Asset& asset = test_asset();
  const fs::path d = test::scratch_dir("bad");
  auto error_of = [&](const MeshAnimation& a, const fs::path& file) -> std::string {
    try {
      write_mesh_animation_glb(file, a);
    } catch (const Error& e) {
      return e.what();
    }
    return "";
  };
  MeshAnimation twice = takes_of(asset);
  twice.clips.push_back(twice.clips.front());
  EXPECT_NE(error_of(twice, d / "twice.glb").find("two clips are named"), std::string::npos);
  MeshAnimation short_frame = takes_of(asset);
  short_frame.clips[1].positions[2].pop_back();
  const std::string e = error_of(short_frame, d / "short.glb");
  EXPECT_NE(e.find("short.glb"), std::string::npos) << e;
  EXPECT_NE(e.find("frame 2"), std::string::npos) << e;
  EXPECT_FALSE(fs::exists(d / "short.glb"));
  write_file_atomic(d / "a_file", "x");
  EXPECT_THROW(write_mesh_animation_glb(d / "a_file" / "out.glb", takes_of(asset)), IoError);
}

int run_export(const std::string& args, std::string* output) {
  const fs::path bin = fs::path(FOURD_BIN_DIR) / "fourd-export";
  const fs::path log = test::scratch_dir("cli") / "out.txt";
  const int status =
      std::system((bin.string() + " " + args + " >" + log.string() + " 2>&1").c_str());
  *output = read_file(log);
  return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

TEST(ExportExecutable, RefusesBadInputWithAClearMessage) {
  if (!fs::exists(fs::path(FOURD_BIN_DIR) / "fourd-export")) GTEST_SKIP() << "not built";
  const fs::path d = test::scratch_dir("cli_inputs");
  save_asset(d / "motion_graph.fourd", test_asset());
  std::string out;
  EXPECT_EQ(run_export((d / "motion_graph.fourd").string() + " -o " + (d / "ok.glb").string(), &out),
            kExitOk)
      << out;
  EXPECT_TRUE(fs::exists(d / "ok.glb"));
  // A corrupt asset: named, exit 4, nothing written.
  std::string bytes = read_file(d / "motion_graph.fourd");
  bytes[bytes.size() / 3] ^= 0x10;
  write_file_atomic(d / "corrupt.fourd", bytes);
  EXPECT_EQ(run_export((d / "corrupt.fourd").string() + " -o " + (d / "c.glb").string(), &out),
            kExitInput);
  EXPECT_NE(out.find("corrupt.fourd"), std::string::npos) << out;
  EXPECT_FALSE(fs::exists(d / "c.glb"));
  // An output path that cannot be written: named, exit 5.
  write_file_atomic(d / "a_file", "x");
  const fs::path unwritable = d / "a_file" / "out.glb";
  EXPECT_EQ(run_export((d / "motion_graph.fourd").string() + " -o " + unwritable.string(), &out),
            kExitIo);
  EXPECT_NE(out.find((d / "a_file").string()), std::string::npos) << out;
  // A script naming a space the asset does not have: its line, exit 4.
  write_file_atomic(d / "bad.txt", "start flying 1\n");
  EXPECT_EQ(run_export((d / "motion_graph.fourd").string() + " -o " + (d / "s.glb").string() +
                           " --script " + (d / "bad.txt").string(),
                       &out),
            kExitInput);
  EXPECT_NE(out.find("bad.txt:1: unknown motion space 'flying'"), std::string::npos) << out;
}

}  // namespace
}  // namespace fourd
