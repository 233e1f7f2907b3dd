#pragma once
// The viewer's OpenGL 3.3 core renderer: the blended character, the ground grid and overlay
// lines. Needs a current OpenGL 3.3 context (the viewer's GLFW window) for every call.
//
// Character. The topology is uploaded once; per frame the runtime's blended positions and
// normals (runtime/character.h: root frame, planes x | y | z) go into one buffer texture as they
// are, and the vertex shader reads them by vertex index and applies the root transform, so the
// CPU does no per-vertex work. Shading is Lambert plus a sky/ground hemisphere light from the
// blended normals.
//
// Key textures. An asset with captured appearance has per-corner atlas UVs and a set of key
// textures; upload_key_textures() puts them all into one texture array, once, and duplicates the
// vertices whose corners disagree in UV (chart seams). Per frame set_key_blend() hands over which
// layers the runtime blends and with what weights (at most kMaxKeyLayers), and the fragment
// shader blends them on the GPU. Without key textures the character is shaded in one colour.
#include <array>
#include <cstdint>
#include <span>
#include <vector>

#include "pipeline/core/mesh.h"
#include "runtime/character.h"
#include "runtime/viewer/view_math.h"

namespace fourd::viewer {

inline constexpr int kMaxKeyLayers = 12;

struct LineVertex {
  float x, y, z;
  float r, g, b;
};

class Renderer {
 public:
  Renderer();
  ~Renderer();
  Renderer(const Renderer&) = delete;
  Renderer& operator=(const Renderer&) = delete;

  // The character's topology (#F triangles over num_vertices vertices), shaded in one colour.
  // Throws InputError for a triangle that names a vertex out of range.
  void set_mesh(std::span<const Tri> triangles, int num_vertices);
  // Key textures: `images` are width x height BGR, 8 bits, rows top to bottom, one layer each;
  // corner_uvs are #F x 3 (corner c of face f at 3 f + c), v up. Call after set_mesh. Throws
  // InputError when the sizes disagree, ConfigError when the GPU cannot hold the array.
  void upload_key_textures(int width, int height, std::span<const std::uint8_t* const> images,
                           std::span<const Vec2f> corner_uvs);
  bool textured() const { return num_layers_ > 0; }
  int num_layers() const { return num_layers_; }
  // The layers the next draw blends and their weights (count <= kMaxKeyLayers; layers in range).
  void set_key_blend(std::span<const int> layers, std::span<const float> weights);

  // The runtime's frame: blended positions and normals in the root frame, and the root.
  void update_character(const CharacterFrame& frame);

  void begin_frame(int width, int height);  // viewport, clear
  void draw_ground(const Mat4f& view_projection, float centre_x, float centre_y);
  void draw_character(const Mat4f& view_projection, const Eigen::Vector3f& eye);
  // Lines (pairs of vertices) or a strip, one pixel wide; points as squares.
  void draw_lines(const Mat4f& view_projection, std::span<const LineVertex> vertices, bool strip);
  void draw_points(const Mat4f& view_projection, std::span<const LineVertex> vertices,
                   float size_pixels);

 private:
  unsigned character_program_ = 0, line_program_ = 0;
  unsigned character_vao_ = 0, character_vbo_ = 0, character_ibo_ = 0;
  unsigned shape_buffer_ = 0, shape_texture_ = 0;  // positions + normals, buffer texture
  unsigned key_texture_ = 0;
  unsigned line_vao_ = 0, line_vbo_ = 0;
  int num_vertices_ = 0, plane_stride_ = 0, num_indices_ = 0;
  int num_layers_ = 0;
  std::vector<Tri> triangles_;
  RootTransform root_;
  std::array<int, kMaxKeyLayers> layers_{};
  std::array<float, kMaxKeyLayers> weights_{};
  int blend_count_ = 0;
  std::vector<LineVertex> grid_;  // the ground's vertices (rebuilt in place every frame)

  void draw_primitives(const Mat4f& view_projection, std::span<const LineVertex> vertices,
                       unsigned mode, float point_size);
};

}  // namespace fourd::viewer
