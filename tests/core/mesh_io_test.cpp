#include "pipeline/core/mesh_io.h"

#include <fmt/format.h>
#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstring>
#include <fstream>
#include <numbers>

#include "pipeline/core/error.h"
#include "pipeline/core/files.h"
#include "tests/input_error.h"
#include "tests/test_shapes.h"

namespace fourd {
namespace {

class MeshIoTest : public ::testing::Test {
 protected:
  void SetUp() override {
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    dir_ = fs::temp_directory_path() / fmt::format("fourd_mesh_io_{}_{}", ::getpid(), info->name());
    fs::remove_all(dir_);
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }

  fs::path path(const std::string& name) const { return dir_ / name; }
  fs::path write_text(const std::string& name, std::string_view text) const {
    std::ofstream(path(name), std::ios::binary) << text;
    return path(name);
  }
  // Names of the files in the test folder (to see that no temp files are left behind).
  std::vector<std::string> files() const {
    std::vector<std::string> names;
    for (const auto& entry : fs::directory_iterator(dir_)) names.push_back(entry.path().filename());
    std::sort(names.begin(), names.end());
    return names;
  }

  fs::path dir_;
};

using test::input_error;

bool contains(const std::string& text, std::string_view part) {
  return text.find(part) != std::string::npos;
}

// An icosphere with every per-vertex attribute: normals, colours, spherical UVs, confidence.
Mesh make_attributed_sphere() {
  Mesh mesh = test::make_icosphere(2, 0.7f);
  compute_vertex_normals(mesh);
  for (std::size_t i = 0; i < mesh.num_vertices(); ++i) {
    const Vec3f& p = mesh.positions[i];
    mesh.colors.emplace_back(i % 256, (i * 7) % 256, 255 - i % 256);
    mesh.confidence.push_back(static_cast<float>(i % 11) / 10.0f);
    mesh.uvs.emplace_back(
        0.5f + std::atan2(p.y(), p.x()) / (2 * std::numbers::pi_v<float>),
        std::acos(std::clamp(p.z() / 0.7f, -1.f, 1.f)) / std::numbers::pi_v<float>);
  }
  return mesh;
}

// Per-corner UVs: every triangle gets its own three UVs (a seam everywhere).
Mesh make_corner_uv_box() {
  Mesh mesh = test::make_box(Vec3f(1, 2, 3));
  for (std::size_t f = 0; f < mesh.num_triangles(); ++f) {
    int base = static_cast<int>(mesh.uvs.size());
    float u = 0.05f * static_cast<float>(f);
    mesh.uvs.insert(mesh.uvs.end(), {{u, 0.1f}, {u + 0.03f, 0.2f}, {u, 0.3f}});
    mesh.uv_triangles.emplace_back(base, base + 1, base + 2);
  }
  mesh.texture = "textures/skin.png";
  return mesh;
}

void expect_same_mesh(const Mesh& a, const Mesh& b) {
  EXPECT_EQ(a.positions, b.positions);
  EXPECT_EQ(a.triangles, b.triangles);
  EXPECT_EQ(a.normals, b.normals);
  EXPECT_EQ(a.colors, b.colors);
  EXPECT_EQ(a.confidence, b.confidence);
  EXPECT_EQ(a.uvs, b.uvs);
  EXPECT_EQ(a.uv_triangles, b.uv_triangles);
  EXPECT_EQ(a.texture, b.texture);
}

TEST_F(MeshIoTest, PlyBinaryRoundTripIsExact) {
  Mesh mesh = make_attributed_sphere();
  write_ply(path("sphere.ply"), mesh);
  expect_same_mesh(read_ply(path("sphere.ply")), mesh);
  EXPECT_EQ(files(), std::vector<std::string>{"sphere.ply"});  // no temp file left
}

TEST_F(MeshIoTest, PlyAsciiRoundTripIsExact) {
  Mesh mesh = make_attributed_sphere();
  write_ply(path("sphere.ply"), mesh, PlyFormat::kAscii);
  EXPECT_TRUE(contains(read_file(path("sphere.ply")), "format ascii 1.0"));
  EXPECT_TRUE(contains(read_file(path("sphere.ply")), "property float s\nproperty float t\n"));
  expect_same_mesh(read_ply(path("sphere.ply")), mesh);
}

TEST_F(MeshIoTest, PlyRoundTripWithCornerUvsAndTexture) {
  Mesh mesh = make_corner_uv_box();
  for (PlyFormat format : {PlyFormat::kBinary, PlyFormat::kAscii}) {
    write_ply(path("box.ply"), mesh, format);
    Mesh back = read_ply(path("box.ply"));
    EXPECT_EQ(back.positions, mesh.positions);
    EXPECT_EQ(back.triangles, mesh.triangles);
    EXPECT_EQ(back.texture, "textures/skin.png");
    ASSERT_EQ(back.uv_triangles.size(), mesh.num_triangles());
    for (std::size_t f = 0; f < mesh.num_triangles(); ++f) {
      for (int k = 0; k < 3; ++k) {
        EXPECT_EQ(back.uvs[back.uv_triangles[f][k]], mesh.uvs[mesh.uv_triangles[f][k]]);
      }
    }
  }
}

TEST_F(MeshIoTest, PlyWithoutFacesIsAPointCloud) {
  Mesh mesh;
  mesh.positions = {{1, 2, 3}, {4, 5, 6}};
  write_ply(path("points.ply"), mesh);
  Mesh back = read_ply(path("points.ply"));
  EXPECT_EQ(back.positions, mesh.positions);
  EXPECT_TRUE(back.triangles.empty());
}

TEST_F(MeshIoTest, PlyAsciiQuadsExtraPropertiesAndOtherNames) {
  // Doubles, confidence, an alpha channel and an unknown list on vertices; "u v"
  // coordinates; "vertex_index" with uint indices, a quad and a pentagon; an extra face
  // property and an unknown element; comments and CRLF line ends.
  const fs::path file = write_text("quads.ply",
                                   "ply\r\n"
                                   "format ascii 1.0\r\n"
                                   "comment made by hand\r\n"
                                   "element vertex 5\r\n"
                                   "property double x\r\n"
                                   "property double y\r\n"
                                   "property double z\r\n"
                                   "property float confidence\r\n"
                                   "property uchar red\r\n"
                                   "property uchar green\r\n"
                                   "property uchar blue\r\n"
                                   "property uchar alpha\r\n"
                                   "property list uchar int neighbours\r\n"
                                   "property float u\r\n"
                                   "property float v\r\n"
                                   "element face 2\r\n"
                                   "property uchar flags\r\n"
                                   "property list uchar uint vertex_index\r\n"
                                   "element edge 1\r\n"
                                   "property int vertex1\r\n"
                                   "property int vertex2\r\n"
                                   "end_header\r\n"
                                   "0 0 0 0.5 255 0 0 255 2 1 2 0 0\r\n"
                                   "1 0 0 0.5 0 255 0 255 0 1 0\r\n"
                                   "\r\n"
                                   "1 1 0 0.5 0 0 255 255 1 4 1 1\r\n"
                                   "0 1 0 0.5 10 20 30 255 0 0 1\r\n"
                                   "0.5 0.5 1 0.5 1 2 3 4 0 0.5 0.5\r\n"
                                   "7 4 0 1 2 3\r\n"
                                   "7 5 0 1 2 3 4\r\n"
                                   "0 1\r\n");
  Mesh mesh = read_ply(file);
  ASSERT_EQ(mesh.num_vertices(), 5u);
  EXPECT_EQ(mesh.positions[4], Vec3f(0.5f, 0.5f, 1));
  EXPECT_EQ(mesh.colors[3], Rgb8(10, 20, 30));
  EXPECT_EQ(mesh.confidence, std::vector<float>(5, 0.5f));
  ASSERT_EQ(mesh.uvs.size(), 5u);
  EXPECT_EQ(mesh.uvs[2], Vec2f(1, 1));
  EXPECT_TRUE(mesh.normals.empty());
  // Quad -> 2 triangles, pentagon -> 3, fanned around the first corner.
  ASSERT_EQ(mesh.num_triangles(), 5u);
  EXPECT_EQ(mesh.triangles[0], Tri(0, 1, 2));
  EXPECT_EQ(mesh.triangles[1], Tri(0, 2, 3));
  EXPECT_EQ(mesh.triangles[4], Tri(0, 3, 4));
}

TEST_F(MeshIoTest, PlyMeshLabConventions) {
  // As MeshLab writes them: texture_u/texture_v, alpha, per-corner "texcoord", TextureFile.
  const fs::path file = write_text("meshlab.ply",
                                   "ply\nformat ascii 1.0\ncomment VCGLIB generated\n"
                                   "comment TextureFile tex/albedo.png\n"
                                   "element vertex 3\n"
                                   "property float x\nproperty float y\nproperty float z\n"
                                   "property uchar red\nproperty uchar green\nproperty uchar blue\n"
                                   "property uchar alpha\n"
                                   "property float texture_u\nproperty float texture_v\n"
                                   "element face 1\n"
                                   "property list uchar int vertex_indices\n"
                                   "property list uchar float texcoord\n"
                                   "end_header\n"
                                   "0 0 0 1 2 3 255 0.1 0.2\n"
                                   "1 0 0 4 5 6 255 0.3 0.4\n"
                                   "0 1 0 7 8 9 255 0.5 0.6\n"
                                   "3 0 1 2 6 0.9 0.8 0.7 0.6 0.5 0.4\n");
  Mesh mesh = read_ply(file);
  EXPECT_EQ(mesh.texture, "tex/albedo.png");
  EXPECT_EQ(mesh.colors[2], Rgb8(7, 8, 9));
  // Per-corner coordinates win over per-vertex ones.
  ASSERT_EQ(mesh.uv_triangles.size(), 1u);
  EXPECT_EQ(mesh.uvs[mesh.uv_triangles[0][1]], Vec2f(0.7f, 0.6f));

  const fs::path odd = write_text("odd.ply",
                                  "ply\nformat ascii 1.0\nelement vertex 3\n"
                                  "property float x\nproperty float y\nproperty float z\n"
                                  "element face 1\nproperty list uchar int vertex_indices\n"
                                  "property list uchar float texcoord\nend_header\n"
                                  "0 0 0\n1 0 0\n0 1 0\n3 0 1 2 5 0 0 1 0 1\n");
  EXPECT_TRUE(contains(input_error([&] { read_ply(odd); }), "odd.ply:14: odd texcoord length 5"));
}

// Appends `value` to `out` in the given byte order.
template <class T>
void put(std::string& out, T value, bool big_endian = false) {
  char bytes[sizeof(T)];
  std::memcpy(bytes, &value, sizeof(T));
  if (big_endian != (std::endian::native == std::endian::big))
    std::reverse(bytes, bytes + sizeof(T));
  out.append(bytes, sizeof(T));
}

// A binary PLY of a unit quad (4 vertices, one 4-corner face) with double positions, float
// normals, an unknown int property and an unknown list, in either byte order.
std::string binary_quad_ply(bool big_endian) {
  std::string text = fmt::format(
      "ply\nformat {} 1.0\n"
      "element vertex 4\n"
      "property double x\nproperty double y\nproperty double z\n"
      "property int id\n"
      "property float nx\nproperty float ny\nproperty float nz\n"
      "element face 1\n"
      "property list uchar int vertex_indices\n"
      "property list int short unknown_list\n"
      "end_header\n",
      big_endian ? "binary_big_endian" : "binary_little_endian");
  const double xy[4][2] = {{0, 0}, {1, 0}, {1, 1}, {0, 1}};
  for (int i = 0; i < 4; ++i) {
    put(text, xy[i][0], big_endian);
    put(text, xy[i][1], big_endian);
    put(text, 0.25, big_endian);
    put(text, std::int32_t{100 + i}, big_endian);
    put(text, 0.f, big_endian);
    put(text, 0.f, big_endian);
    put(text, 1.f, big_endian);
  }
  put(text, std::uint8_t{4});
  for (int i = 0; i < 4; ++i) put(text, std::int32_t{i}, big_endian);
  put(text, std::int32_t{2}, big_endian);
  put(text, std::int16_t{-1}, big_endian);
  put(text, std::int16_t{7}, big_endian);
  return text;
}

TEST_F(MeshIoTest, PlyBinaryQuadWithDoublesAndUnknownProperties) {
  for (bool big_endian : {false, true}) {
    Mesh mesh = read_ply(write_text("quad.ply", binary_quad_ply(big_endian)));
    ASSERT_EQ(mesh.num_vertices(), 4u) << "big endian " << big_endian;
    EXPECT_EQ(mesh.positions[2], Vec3f(1, 1, 0.25f));
    EXPECT_EQ(mesh.normals[3], Vec3f(0, 0, 1));
    ASSERT_EQ(mesh.num_triangles(), 2u);
    EXPECT_EQ(mesh.triangles[0], Tri(0, 1, 2));
    EXPECT_EQ(mesh.triangles[1], Tri(0, 2, 3));
  }
}

TEST_F(MeshIoTest, PlyTruncatedBinaryThrowsNamingTheFile) {
  std::string bytes = binary_quad_ply(false);
  for (std::size_t cut : {std::size_t{10}, std::size_t{30}, std::size_t{1}}) {
    const fs::path file = write_text("cut.ply", bytes.substr(0, bytes.size() - cut));
    std::string message = input_error([&] { read_ply(file); });
    EXPECT_TRUE(contains(message, "cut.ply")) << message;
    EXPECT_TRUE(contains(message, "truncated")) << message;
  }
  // Cut inside the vertices: the message names the element and its index.
  const fs::path file =
      write_text("cut.ply", bytes.substr(0, bytes.find("end_header\n") + 11 + 50));
  std::string message = input_error([&] { read_ply(file); });
  EXPECT_TRUE(contains(message, "vertex 1 of 4")) << message;
  // Cut inside the header.
  const fs::path header = write_text("header.ply", "ply\nformat ascii 1.0\nelement vertex 3\n");
  EXPECT_TRUE(contains(input_error([&] { read_ply(header); }), "truncated"));
}

TEST_F(MeshIoTest, PlyHugeCountsDoNotAllocate) {
  std::string text =
      "ply\nformat binary_little_endian 1.0\nelement vertex 4000000000000\n"
      "property float x\nproperty float y\nproperty float z\nend_header\n";
  put(text, 1.f);
  const fs::path file = write_text("huge.ply", text);
  EXPECT_TRUE(contains(input_error([&] { read_ply(file); }), "truncated"));

  // A face whose corner count claims four billion indices.
  std::string list =
      "ply\nformat binary_little_endian 1.0\nelement vertex 1\n"
      "property float x\nproperty float y\nproperty float z\n"
      "element face 1\nproperty list uint int vertex_indices\nend_header\n";
  for (int k = 0; k < 3; ++k) put(list, 0.f);
  put(list, std::uint32_t{0xffffffffu});
  for (int k = 0; k < 3; ++k) put(list, std::int32_t{0});
  const fs::path file2 = write_text("list.ply", list);
  std::string message = input_error([&] { read_ply(file2); });
  EXPECT_TRUE(contains(message, "truncated")) << message;
  EXPECT_TRUE(contains(message, "face 0 of 1")) << message;
}

TEST_F(MeshIoTest, PlyMalformedAsciiNamesFileAndLine) {
  const std::string header =
      "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
      "property float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n";
  struct Case {
    std::string body;
    std::string expected;
  };
  const std::vector<Case> cases = {
      {"0 0 0\n1 0 zero\n0 1 0\n3 0 1 2\n", "bad.ply:11: \"zero\" is not a number"},
      {"0 0 0\n1 0\n0 1 0\n3 0 1 2\n", "bad.ply:11: fewer values"},
      {"0 0 0\n1 0 0 7\n0 1 0\n3 0 1 2\n", "bad.ply:11: more values"},
      {"0 0 0\n1 0 0\n0 1 0\n3 0 1 3\n", "bad.ply:13: vertex index 3 out of range"},
      {"0 0 0\n1 0 0\n0 1 0\n3 0 -1 2\n", "bad.ply:13: vertex index -1 out of range"},
      {"0 0 0\n1 0 0\n0 1 0\n2 0 1\n", "bad.ply:13: face with 2 vertices"},
      {"0 0 0\n1 0 0\n0 1 0\n", "truncated"},
      {"0 0 0\n1 0 0\nnan 1 0\n3 0 1 2\n", "not finite"},
  };
  for (const Case& c : cases) {
    const fs::path file = write_text("bad.ply", header + c.body);
    std::string message = input_error([&] { read_ply(file); });
    EXPECT_TRUE(contains(message, c.expected)) << message << " (expected " << c.expected << ")";
    EXPECT_TRUE(contains(message, "bad.ply")) << message;
  }
}

TEST_F(MeshIoTest, PlyBadHeaders) {
  EXPECT_TRUE(contains(input_error([&] { read_ply(write_text("a.ply", "OFF\n3 1 0\n")); }),
                       "not a PLY file"));
  EXPECT_TRUE(contains(input_error([&] {
                         read_ply(write_text("b.ply",
                                             "ply\nformat binary_middle_endian 1.0\nend_header\n"));
                       }),
                       "b.ply:2: unknown PLY format"));
  EXPECT_TRUE(contains(input_error([&] {
                         read_ply(write_text("c.ply",
                                             "ply\nformat ascii 1.0\nelement vertex 1\n"
                                             "property quaternion x\nend_header\n"));
                       }),
                       "c.ply:4: unknown property type"));
  EXPECT_TRUE(contains(input_error([&] {
                         read_ply(write_text("d.ply",
                                             "ply\nformat ascii 1.0\nelement vertex 1\n"
                                             "property float x\nend_header\n1\n"));
                       }),
                       "no x, y and z"));
  EXPECT_THROW(read_ply(path("missing.ply")), IoError);
}

TEST_F(MeshIoTest, ObjRoundTripWithCornerUvsAndTexture) {
  Mesh mesh = make_corner_uv_box();
  compute_vertex_normals(mesh);
  write_obj(path("box.obj"), mesh);
  EXPECT_EQ(files(), (std::vector<std::string>{"box.mtl", "box.obj"}));
  const std::string mtl = read_file(path("box.mtl"));
  EXPECT_TRUE(contains(mtl, "map_Kd textures/skin.png")) << mtl;
  const std::string obj = read_file(path("box.obj"));
  EXPECT_TRUE(contains(obj, "mtllib box.mtl\n")) << obj;
  EXPECT_TRUE(contains(obj, "usemtl ")) << obj;
  expect_same_mesh(read_obj(path("box.obj")), mesh);
}

TEST_F(MeshIoTest, ObjRoundTripWithVertexAttributes) {
  Mesh mesh = make_attributed_sphere();
  mesh.confidence.clear();  // OBJ has no place for it
  write_mesh(path("sphere.obj"), mesh);
  EXPECT_EQ(files(), std::vector<std::string>{"sphere.obj"});  // no texture: no .mtl
  expect_same_mesh(read_mesh(path("sphere.obj")), mesh);

  Mesh plain = test::make_box();
  write_obj(path("plain.obj"), plain);
  expect_same_mesh(read_obj(path("plain.obj")), plain);
}

TEST_F(MeshIoTest, ObjReaderFormsNegativeIndicesAndMaterials) {
  fs::create_directories(path("materials"));
  write_text("materials/lib.mtl",
             "newmtl other\nmap_Kd wrong.png\n"
             "newmtl skin\nKd 1 1 1\nmap_Kd -s 1 1 1 -clamp on ..\\tex\\skin map.png\n");
  const fs::path file = write_text("shape.obj",
                                   "# comment\n"
                                   "mtllib materials/lib.mtl\n"
                                   "o shape\n"
                                   "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0  # trailing comment\n"
                                   "vt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\n"
                                   "vn 0 0 1\n"
                                   "usemtl skin\n"
                                   "s off\n"
                                   "f -4/-4/-1 -3/-3/-1 -2/-2/-1 -1/-1/-1\n");
  Mesh mesh = read_obj(file);
  EXPECT_EQ(mesh.texture, "tex/skin map.png");
  ASSERT_EQ(mesh.num_triangles(), 2u);
  EXPECT_EQ(mesh.triangles[1], Tri(0, 2, 3));
  // vt index == v index everywhere: per-vertex coordinates.
  EXPECT_TRUE(mesh.uv_triangles.empty());
  EXPECT_EQ(mesh.uvs[2], Vec2f(1, 1));
  ASSERT_EQ(mesh.normals.size(), 4u);
  EXPECT_EQ(mesh.normals[3], Vec3f(0, 0, 1));

  Mesh normals_only =
      read_obj(write_text("n.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nvn 0 0 1\nf 1//1 2//1 3//1\n"));
  EXPECT_TRUE(normals_only.uvs.empty());
  EXPECT_EQ(normals_only.normals[1], Vec3f(0, 0, 1));

  Mesh seams = read_obj(
      write_text("seam.obj",
                 "v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nvt 1 0\nvt 0 1\nvt 0.5 0.5\nf 1/4 2/2 3/3\n"));
  ASSERT_EQ(seams.uv_triangles.size(), 1u);
  EXPECT_EQ(seams.uvs[seams.uv_triangles[0][0]], Vec2f(0.5f, 0.5f));
  EXPECT_TRUE(seams.texture.empty());

  // Without usemtl, the library's first textured material; a missing library is not fatal.
  write_text("plain.mtl", "newmtl a\nKd 1 0 0\nnewmtl b\nmap_Kd b.png\n");
  Mesh no_usemtl = read_obj(write_text(
      "plain.obj", "mtllib plain.mtl\nmtllib gone.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n"));
  EXPECT_EQ(no_usemtl.texture, "b.png");
  Mesh missing = read_obj(
      write_text("missing.obj", "mtllib gone.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nusemtl x\nf 1 2 3\n"));
  EXPECT_TRUE(missing.texture.empty());
  EXPECT_EQ(missing.num_triangles(), 1u);
}

TEST_F(MeshIoTest, ObjMalformedNamesFileAndLine) {
  struct Case {
    std::string text;
    std::string expected;
  };
  const std::vector<Case> cases = {
      {"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 4\n", "bad.obj:4: vertex index 4 out of range"},
      {"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 -4\n", "bad.obj:4: vertex index -4 out of range"},
      {"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 0\n", "bad.obj:4: bad vertex index"},
      {"v 0 0 0\nv 1 0 0\nv 0 x 0\n", "bad.obj:3: \"x\" is not a number"},
      {"v 0 0\n", "bad.obj:1: a vertex needs"},
      {"v 0 0 0\nv 1 0 0\nf 1 2\n", "bad.obj:3: face with 2 vertices"},
      {"v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nf 1/1 2/1 3/2\n",
       "bad.obj:5: texture coordinate index 2"},
      {"v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nf 1/1 2/1 3/1\nf 1 2 3\n", "bad.obj:6: some faces have"},
  };
  for (const Case& c : cases) {
    const fs::path file = write_text("bad.obj", c.text);
    std::string message = input_error([&] { read_obj(file); });
    EXPECT_TRUE(contains(message, c.expected)) << message << " (expected " << c.expected << ")";
  }
}

TEST_F(MeshIoTest, UnknownExtensionAndInvalidMeshAreRefused) {
  EXPECT_THROW(write_mesh(path("mesh.stl"), test::make_box()), InputError);
  EXPECT_THROW(read_mesh(path("mesh.off")), InputError);
  Mesh bad = test::make_box();
  bad.triangles[0][0] = 42;
  EXPECT_THROW(write_ply(path("bad.ply"), bad), InputError);
  EXPECT_FALSE(fs::exists(path("bad.ply")));
}

TEST_F(MeshIoTest, FailedWriteLeavesPreviousFile) {
  Mesh box = test::make_box();
  write_ply(path("box.ply"), box);
  Mesh bad = box;
  bad.normals.resize(2);
  EXPECT_THROW(write_ply(path("box.ply"), bad), InputError);
  expect_same_mesh(read_ply(path("box.ply")), box);
}

}  // namespace
}  // namespace fourd
