#include "stages/synth/gltf_io.h"

#include <gtest/gtest.h>

// The test edits exported files with tinygltf itself; the macros must match gltf_io.cpp's.
#define TINYGLTF_NO_STB_IMAGE
#define TINYGLTF_NO_STB_IMAGE_WRITE
#include <tiny_gltf.h>

#include <cstring>
#include <filesystem>
#include <fstream>
#include <numbers>
#include <random>

#include "pipeline/core/error.h"
#include "tests/synth/test_character.h"

namespace fourd::synth {
namespace {

namespace fs = std::filesystem;

using test::make_test_character;
using test::make_test_clip;

double max_skinned_error(const Character& a, const Pose& pa, const Character& b, const Pose& pb) {
  const Mesh ma = skin_mesh(a.skin, forward_kinematics(a.skeleton, pa));
  const Mesh mb = skin_mesh(b.skin, forward_kinematics(b.skeleton, pb));
  EXPECT_EQ(ma.num_vertices(), mb.num_vertices());
  double worst = 0;
  for (std::size_t v = 0; v < std::min(ma.num_vertices(), mb.num_vertices()); ++v)
    worst = std::max(worst, static_cast<double>((ma.positions[v] - mb.positions[v]).norm()));
  return worst;
}

fs::path temp_dir(const std::string& name) {
  const fs::path dir = fs::temp_directory_path() / ("fourd_gltf_io_test_" + name);
  fs::remove_all(dir);
  fs::create_directories(dir);
  return dir;
}

// tinygltf for editing exported files: images are kept as they are (no decoding).
bool keep_image(tinygltf::Image*, const int, std::string*, std::string*, int, int,
                const unsigned char*, int, void*) {
  return true;
}

tinygltf::Model load_model(const fs::path& path) {
  tinygltf::TinyGLTF loader;
  loader.SetImageLoader(keep_image, nullptr);
  tinygltf::Model model;
  std::string err, warn;
  EXPECT_TRUE(loader.LoadBinaryFromFile(&model, &err, &warn, path.string())) << err;
  return model;
}

void save_model(const tinygltf::Model& model, const fs::path& path) {
  tinygltf::TinyGLTF writer;
  std::ofstream out(path, std::ios::binary);
  ASSERT_TRUE(writer.WriteGltfSceneToStream(&model, out, false, true));
}

// The float elements of a tightly packed float accessor, in place.
float* floats(tinygltf::Model& model, int accessor) {
  const tinygltf::Accessor& a = model.accessors[accessor];
  const tinygltf::BufferView& v = model.bufferViews[a.bufferView];
  return reinterpret_cast<float*>(model.buffers[v.buffer].data.data() + v.byteOffset +
                                  a.byteOffset);
}

TEST(GltfIo, ExportedCharacterReadsBackWithTheSameSkinnedSurface) {
  const fs::path dir = temp_dir("roundtrip");
  const Character original = make_test_character();
  const std::vector<MotionClip> clips = {make_test_clip(original.skeleton, "walk_slow", 12, 25, 1),
                                         make_test_clip(original.skeleton, "jump_long", 7, 30, 2)};
  write_gltf_character(dir / "column.glb", original, clips);
  const ImportedCharacter imported = read_gltf_character(dir / "column.glb");

  EXPECT_EQ(imported.character.name, "column");
  EXPECT_EQ(imported.character.skeleton.names, original.skeleton.names);
  EXPECT_EQ(imported.character.skeleton.parents, original.skeleton.parents);
  for (std::size_t j = 0; j < original.skeleton.size(); ++j)
    EXPECT_LT(
        (imported.character.skeleton.rest_offsets[j] - original.skeleton.rest_offsets[j]).norm(),
        1e-6);
  ASSERT_EQ(imported.character.skin.rest.num_vertices(), original.skin.rest.num_vertices());
  EXPECT_EQ(imported.character.skin.rest.triangles, original.skin.rest.triangles);
  for (std::size_t v = 0; v < original.skin.rest.num_vertices(); ++v)
    EXPECT_LT((imported.character.skin.rest.uvs[v] - original.skin.rest.uvs[v]).norm(), 1e-6);
  ASSERT_EQ(imported.character.texture.size(), original.texture.size());
  EXPECT_EQ(cv::norm(imported.character.texture, original.texture, cv::NORM_INF), 0);

  ASSERT_EQ(imported.clips.size(), clips.size());
  for (std::size_t c = 0; c < clips.size(); ++c) {
    const MotionClip& in = imported.clips[c];
    EXPECT_EQ(in.spec.take, clips[c].spec.take);
    EXPECT_DOUBLE_EQ(in.fps, clips[c].fps);
    ASSERT_EQ(in.poses.size(), clips[c].poses.size());
    ASSERT_EQ(in.root.size(), in.poses.size());
    for (std::size_t f = 0; f < in.poses.size(); ++f) {
      EXPECT_LT(max_skinned_error(original, clips[c].poses[f], imported.character, in.poses[f]),
                1e-4)
          << clips[c].spec.take << " frame " << f;
      EXPECT_LT((in.root[f].position - clips[c].poses[f].root_position.head<2>()).norm(), 1e-5);
    }
  }
}

// Real exporters give joints rotated rest frames and put the skeleton under a scaled, turned
// armature node (Blender: centimetres, z-up turned to y-up). The same motion written that way
// must import to the same surface.
TEST(GltfIo, RotatedJointFramesAndScaledArmatureImportToTheSameSurface) {
  const fs::path dir = temp_dir("rotated");
  const Character original = make_test_character();
  const std::vector<MotionClip> clips = {make_test_clip(original.skeleton, "reach", 9, 25, 3)};
  write_gltf_character(dir / "plain.glb", original, clips);
  tinygltf::Model model = load_model(dir / "plain.glb");

  const int joints = static_cast<int>(original.skeleton.size());
  const double s = 0.01;  // armature scale: joint translations are in centimetres
  const Eigen::Quaterniond armature(
      Eigen::AngleAxisd(-std::numbers::pi / 2, Eigen::Vector3d::UnitX()));
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(-1, 1);
  std::vector<Eigen::Quaterniond> frame(joints);  // each joint's frame turned by frame[j]
  for (auto& q : frame) q = Eigen::Quaterniond(u(rng), u(rng), u(rng), u(rng)).normalized();
  auto parent_frame = [&](int j) {
    return j == 0 ? armature : frame[original.skeleton.parents[j]];
  };
  // New local transform: M_p^-1 L M_j with M = frame * scale (the scales cancel).
  for (int j = 0; j < joints; ++j) {
    tinygltf::Node& node = model.nodes[j];
    const Eigen::Vector3d t(node.translation[0], node.translation[1], node.translation[2]);
    const Eigen::Vector3d t2 = parent_frame(j).conjugate() * t / s;
    node.translation = {t2.x(), t2.y(), t2.z()};
    const Eigen::Quaterniond r = parent_frame(j).conjugate() * frame[j];
    node.rotation = {r.x(), r.y(), r.z(), r.w()};
  }
  float* ibm = floats(model, model.skins[0].inverseBindMatrices);
  for (int j = 0; j < joints; ++j) {
    Eigen::Map<Eigen::Matrix4f> m(ibm + 16 * j);  // column-major, as glTF
    Eigen::Matrix4f inverse_frame = Eigen::Matrix4f::Identity();
    inverse_frame.topLeftCorner<3, 3>() = frame[j].conjugate().toRotationMatrix().cast<float>() / s;
    m = (inverse_frame * m).eval();
  }
  for (const tinygltf::AnimationChannel& ch : model.animations[0].channels) {
    const tinygltf::AnimationSampler& sampler = model.animations[0].samplers[ch.sampler];
    float* out = floats(model, sampler.output);
    const std::size_t keys = model.accessors[sampler.output].count;
    const int j = ch.target_node;
    for (std::size_t k = 0; k < keys; ++k) {
      if (ch.target_path == "rotation") {
        const Eigen::Quaterniond r(out[4 * k + 3], out[4 * k], out[4 * k + 1], out[4 * k + 2]);
        const Eigen::Quaterniond r2 = parent_frame(j).conjugate() * r * frame[j];
        const float v[4] = {float(r2.x()), float(r2.y()), float(r2.z()), float(r2.w())};
        std::memcpy(out + 4 * k, v, sizeof v);
      } else {
        const Eigen::Vector3d t(out[3 * k], out[3 * k + 1], out[3 * k + 2]);
        const Eigen::Vector3d t2 = parent_frame(j).conjugate() * t / s;
        for (int c = 0; c < 3; ++c) out[3 * k + c] = static_cast<float>(t2[c]);
      }
    }
  }
  tinygltf::Node armature_node;
  armature_node.name = "Armature";
  armature_node.rotation = {armature.x(), armature.y(), armature.z(), armature.w()};
  armature_node.scale = {s, s, s};
  armature_node.children = {0};
  model.nodes.push_back(armature_node);
  model.scenes[0].nodes = {static_cast<int>(model.nodes.size()) - 1, joints};
  save_model(model, dir / "rotated.glb");

  const ImportedCharacter imported = read_gltf_character(dir / "rotated.glb");
  ASSERT_EQ(imported.character.skeleton.size(), original.skeleton.size());
  for (std::size_t j = 0; j < original.skeleton.size(); ++j)
    EXPECT_LT(
        (imported.character.skeleton.rest_offsets[j] - original.skeleton.rest_offsets[j]).norm(),
        1e-5);
  ASSERT_EQ(imported.clips.size(), 1u);
  ASSERT_EQ(imported.clips[0].poses.size(), clips[0].poses.size());
  for (std::size_t f = 0; f < clips[0].poses.size(); ++f)
    EXPECT_LT(max_skinned_error(original, clips[0].poses[f], imported.character,
                                imported.clips[0].poses[f]),
              1e-4)
        << "frame " << f;
}

// glTF attributes are per vertex: a mesh with per-corner UVs (seams) is split where a vertex
// has several UVs, and every triangle corner keeps its position and UV.
TEST(GltfIo, PerCornerUvsAreSplitIntoVertices) {
  const fs::path dir = temp_dir("seams");
  Character original = make_test_character();
  Mesh& m = original.skin.rest;
  m.uv_triangles = m.triangles;  // per corner, same UVs ...
  const int seam = static_cast<int>(m.uvs.size());
  for (std::size_t v = 0; v < m.num_vertices(); v += 4)  // ... except a seam at corner 0
    m.uvs.emplace_back(m.uvs[v].x() + 0.8f, m.uvs[v].y());
  std::size_t split = 0;
  for (std::size_t f = 0; f < m.num_triangles(); ++f)
    for (int c = 0; c < 3; ++c)
      if (m.triangles[f][c] % 4 == 0 && f % 2 == 1) {
        m.uv_triangles[f][c] = seam + m.triangles[f][c] / 4;
        ++split;
      }
  ASSERT_GT(split, 0u);
  const MotionClip clip = make_test_clip(original.skeleton, "turn", 3, 25, 6);
  write_gltf_character(dir / "seams.glb", original, {clip});
  const ImportedCharacter imported = read_gltf_character(dir / "seams.glb");
  const Mesh& im = imported.character.skin.rest;
  EXPECT_EQ(im.num_vertices(), m.num_vertices() + m.num_vertices() / 4);
  ASSERT_EQ(im.num_triangles(), m.num_triangles());
  for (std::size_t f = 0; f < clip.poses.size(); ++f) {
    const Mesh a = skin_mesh(original.skin, forward_kinematics(original.skeleton, clip.poses[f]));
    const Mesh b =
        skin_mesh(imported.character.skin,
                  forward_kinematics(imported.character.skeleton, imported.clips[0].poses[f]));
    for (std::size_t t = 0; t < m.num_triangles(); ++t)
      for (int c = 0; c < 3; ++c) {
        EXPECT_LT((a.positions[m.triangles[t][c]] - b.positions[im.triangles[t][c]]).norm(), 1e-4);
        EXPECT_LT((m.uvs[m.uv_triangles[t][c]] - im.uvs[im.triangles[t][c]]).norm(), 1e-6);
      }
  }
}

TEST(GltfIo, ResamplesAnimationsAtTheRequestedRate) {
  const fs::path dir = temp_dir("resample");
  const Character original = make_test_character();
  const MotionClip clip = make_test_clip(original.skeleton, "walk", 11, 10, 4);  // 1 s at 10 Hz
  write_gltf_character(dir / "c.glb", original, {clip});
  GltfImportOptions options;
  options.fps = 40;
  const ImportedCharacter imported = read_gltf_character(dir / "c.glb", options);
  ASSERT_EQ(imported.clips.size(), 1u);
  const MotionClip& in = imported.clips[0];
  EXPECT_DOUBLE_EQ(in.fps, 40);
  ASSERT_EQ(in.poses.size(), 41u);
  // Every 4th sample is a key; in between the root moves linearly between keys.
  for (int f = 0; f < 11; ++f)
    EXPECT_LT(max_skinned_error(original, clip.poses[f], imported.character, in.poses[4 * f]),
              1e-4);
  const Eigen::Vector3d mid = 0.5 * (clip.poses[3].root_position + clip.poses[4].root_position);
  EXPECT_LT((in.poses[14].root_position - mid).norm(), 1e-5);
}

TEST(GltfIo, MaterialWithoutTextureGivesAFlatTexture) {
  const fs::path dir = temp_dir("flat");
  write_gltf_character(dir / "c.glb", make_test_character(), {});
  tinygltf::Model model = load_model(dir / "c.glb");
  auto& pbr = model.materials[0].pbrMetallicRoughness;
  pbr.baseColorTexture.index = -1;
  pbr.baseColorFactor = {1.0, 0.2140, 0.0, 1.0};  // linear; sRGB (255, 128, 0)
  save_model(model, dir / "flat.glb");
  const ImportedCharacter imported = read_gltf_character(dir / "flat.glb");
  ASSERT_FALSE(imported.character.texture.empty());
  const cv::Vec3b bgr = imported.character.texture.at<cv::Vec3b>(0, 0);
  EXPECT_EQ(bgr[0], 0);
  EXPECT_NEAR(bgr[1], 128, 1);
  EXPECT_EQ(bgr[2], 255);
  EXPECT_TRUE(imported.clips.empty());
}

TEST(GltfIo, UnusableFilesGiveErrorsNamingFileAndProblem) {
  const fs::path dir = temp_dir("errors");
  write_gltf_character(dir / "c.glb", make_test_character(), {});

  tinygltf::Model model = load_model(dir / "c.glb");
  model.skins.clear();
  for (auto& node : model.nodes) node.skin = -1;
  save_model(model, dir / "unskinned.glb");
  try {
    read_gltf_character(dir / "unskinned.glb");
    FAIL() << "a file without a skin was accepted";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("unskinned.glb"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("no skin"), std::string::npos) << e.what();
  }

  model = load_model(dir / "c.glb");
  // Joint indices stored as floats are not allowed by glTF.
  model.meshes[0].primitives[0].attributes["JOINTS_0"] =
      model.meshes[0].primitives[0].attributes.at("WEIGHTS_0");
  save_model(model, dir / "float_joints.glb");
  try {
    read_gltf_character(dir / "float_joints.glb");
    FAIL() << "float joint indices were accepted";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("float_joints.glb"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("JOINTS_0"), std::string::npos) << e.what();
  }

  model = load_model(dir / "c.glb");
  model.meshes.clear();
  for (auto& node : model.nodes) node.mesh = -1;
  save_model(model, dir / "meshless.glb");
  EXPECT_THROW(read_gltf_character(dir / "meshless.glb"), InputError);

  model = load_model(dir / "c.glb");
  model.extensionsUsed = {"KHR_draco_mesh_compression"};
  model.extensionsRequired = {"KHR_draco_mesh_compression"};
  save_model(model, dir / "draco.glb");
  try {
    read_gltf_character(dir / "draco.glb");
    FAIL() << "a required compression extension was accepted";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("KHR_draco_mesh_compression"), std::string::npos)
        << e.what();
  }

  std::ofstream(dir / "garbage.glb") << "not a glTF file at all";
  EXPECT_THROW(read_gltf_character(dir / "garbage.glb"), InputError);
  EXPECT_THROW(read_gltf_character(dir / "missing.glb"), IoError);
}

}  // namespace
}  // namespace fourd::synth
