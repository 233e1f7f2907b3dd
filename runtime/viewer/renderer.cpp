#include "runtime/viewer/renderer.h"

#include <epoxy/gl.h>
#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <map>
#include <utility>

#include "pipeline/core/error.h"
#include "runtime/blend.h"

namespace fourd::viewer {

namespace {

constexpr const char* kCharacterVertex = R"(#version 330 core
layout(location = 0) in int a_source;
layout(location = 1) in vec2 a_uv;
uniform samplerBuffer u_shape;  // positions x | y | z planes, then normals x | y | z
uniform int u_stride;
uniform vec3 u_root;            // x, y [m], heading [rad]
uniform mat4 u_view_projection;
out vec3 v_world;
out vec3 v_normal;
out vec2 v_uv;
vec3 fetch(int base) {
  return vec3(texelFetch(u_shape, base + a_source).r,
              texelFetch(u_shape, base + u_stride + a_source).r,
              texelFetch(u_shape, base + 2 * u_stride + a_source).r);
}
void main() {
  float c = cos(u_root.z), s = sin(u_root.z);
  mat3 rotation = mat3(c, s, 0.0, -s, c, 0.0, 0.0, 0.0, 1.0);
  v_world = rotation * fetch(0) + vec3(u_root.xy, 0.0);
  v_normal = rotation * fetch(3 * u_stride);
  v_uv = a_uv;
  gl_Position = u_view_projection * vec4(v_world, 1.0);
}
)";

constexpr const char* kCharacterFragment = R"(#version 330 core
in vec3 v_world;
in vec3 v_normal;
in vec2 v_uv;
uniform vec3 u_eye;
uniform vec3 u_albedo;
uniform sampler2DArray u_keys;
uniform int u_count;
uniform int u_layers[12];
uniform float u_weights[12];
out vec4 o_color;
void main() {
  vec3 n = normalize(v_normal);
  if (dot(n, u_eye - v_world) < 0.0) n = -n;  // the inside of an open surface
  const vec3 light = normalize(vec3(0.45, 0.3, 0.84));
  float diffuse = max(dot(n, light), 0.0);
  float sky = 0.5 + 0.5 * n.z;
  vec3 color;
  if (u_count > 0) {
    // The captured appearance, blended on the GPU with the runtime's weights; it already holds
    // the studio's lighting, so shading only adds relief.
    vec3 albedo = vec3(0.0);
    for (int k = 0; k < u_count; ++k) {
      albedo += u_weights[k] * texture(u_keys, vec3(v_uv.x, 1.0 - v_uv.y, float(u_layers[k]))).rgb;
    }
    color = albedo * (0.7 + 0.15 * sky + 0.25 * diffuse);
  } else {
    color = u_albedo * (0.22 + 0.28 * sky + 0.7 * diffuse);
  }
  o_color = vec4(color, 1.0);
}
)";

constexpr const char* kLineVertex = R"(#version 330 core
layout(location = 0) in vec3 a_position;
layout(location = 1) in vec3 a_color;
uniform mat4 u_view_projection;
uniform float u_point_size;
out vec3 v_color;
void main() {
  v_color = a_color;
  gl_PointSize = u_point_size;
  gl_Position = u_view_projection * vec4(a_position, 1.0);
}
)";

constexpr const char* kLineFragment = R"(#version 330 core
in vec3 v_color;
out vec4 o_color;
void main() { o_color = vec4(v_color, 1.0); }
)";

GLuint compile(GLenum kind, const char* source) {
  const GLuint shader = glCreateShader(kind);
  glShaderSource(shader, 1, &source, nullptr);
  glCompileShader(shader);
  GLint ok = 0;
  glGetShaderiv(shader, GL_COMPILE_STATUS, &ok);
  if (!ok) {
    char text[2048];
    glGetShaderInfoLog(shader, sizeof(text), nullptr, text);
    glDeleteShader(shader);
    throw Error(fmt::format("OpenGL shader does not compile: {}", text));
  }
  return shader;
}

GLuint link(const char* vertex, const char* fragment) {
  const GLuint vs = compile(GL_VERTEX_SHADER, vertex), fs = compile(GL_FRAGMENT_SHADER, fragment);
  const GLuint program = glCreateProgram();
  glAttachShader(program, vs);
  glAttachShader(program, fs);
  glLinkProgram(program);
  glDeleteShader(vs);
  glDeleteShader(fs);
  GLint ok = 0;
  glGetProgramiv(program, GL_LINK_STATUS, &ok);
  if (!ok) {
    char text[2048];
    glGetProgramInfoLog(program, sizeof(text), nullptr, text);
    glDeleteProgram(program);
    throw Error(fmt::format("OpenGL program does not link: {}", text));
  }
  return program;
}

GLint uniform(GLuint program, const char* name) { return glGetUniformLocation(program, name); }

// One vertex the GPU draws: the runtime vertex it shows and its atlas UV.
struct DrawVertex {
  GLint source;
  float u, v;
};

}  // namespace

Renderer::Renderer() {
  character_program_ = link(kCharacterVertex, kCharacterFragment);
  line_program_ = link(kLineVertex, kLineFragment);
  glGenVertexArrays(1, &character_vao_);
  glGenBuffers(1, &character_vbo_);
  glGenBuffers(1, &character_ibo_);
  glGenBuffers(1, &shape_buffer_);
  glGenTextures(1, &shape_texture_);
  glGenVertexArrays(1, &line_vao_);
  glGenBuffers(1, &line_vbo_);
  glBindVertexArray(line_vao_);
  glBindBuffer(GL_ARRAY_BUFFER, line_vbo_);
  glEnableVertexAttribArray(0);
  glVertexAttribPointer(0, 3, GL_FLOAT, GL_FALSE, sizeof(LineVertex), nullptr);
  glEnableVertexAttribArray(1);
  glVertexAttribPointer(1, 3, GL_FLOAT, GL_FALSE, sizeof(LineVertex),
                        reinterpret_cast<void*>(3 * sizeof(float)));
  glBindVertexArray(0);
  glEnable(GL_PROGRAM_POINT_SIZE);
}

Renderer::~Renderer() {
  glDeleteProgram(character_program_);
  glDeleteProgram(line_program_);
  glDeleteVertexArrays(1, &character_vao_);
  glDeleteVertexArrays(1, &line_vao_);
  const GLuint buffers[] = {character_vbo_, character_ibo_, shape_buffer_, line_vbo_};
  glDeleteBuffers(4, buffers);
  glDeleteTextures(1, &shape_texture_);
  if (key_texture_) glDeleteTextures(1, &key_texture_);
}

void Renderer::set_mesh(std::span<const Tri> triangles, int num_vertices) {
  for (std::size_t f = 0; f < triangles.size(); ++f) {
    for (int c = 0; c < 3; ++c) {
      if (triangles[f][c] < 0 || triangles[f][c] >= num_vertices) {
        throw InputError(fmt::format("triangle {} names vertex {} of {}", f, triangles[f][c],
                                     num_vertices));
      }
    }
  }
  triangles_.assign(triangles.begin(), triangles.end());
  num_vertices_ = num_vertices;
  plane_stride_ = blend_plane_stride(num_vertices);
  num_layers_ = 0;
  blend_count_ = 0;
  std::vector<DrawVertex> vertices(num_vertices);
  for (int v = 0; v < num_vertices; ++v) vertices[v] = {v, 0, 0};
  std::vector<GLuint> indices;
  indices.reserve(3 * triangles.size());
  for (const Tri& t : triangles) {
    for (int c = 0; c < 3; ++c) indices.push_back(static_cast<GLuint>(t[c]));
  }
  num_indices_ = static_cast<int>(indices.size());

  glBindVertexArray(character_vao_);
  glBindBuffer(GL_ARRAY_BUFFER, character_vbo_);
  glBufferData(GL_ARRAY_BUFFER, vertices.size() * sizeof(DrawVertex), vertices.data(),
               GL_STATIC_DRAW);
  glEnableVertexAttribArray(0);
  glVertexAttribIPointer(0, 1, GL_INT, sizeof(DrawVertex), nullptr);
  glEnableVertexAttribArray(1);
  glVertexAttribPointer(1, 2, GL_FLOAT, GL_FALSE, sizeof(DrawVertex),
                        reinterpret_cast<void*>(sizeof(GLint)));
  glBindBuffer(GL_ELEMENT_ARRAY_BUFFER, character_ibo_);
  glBufferData(GL_ELEMENT_ARRAY_BUFFER, indices.size() * sizeof(GLuint), indices.data(),
               GL_STATIC_DRAW);
  glBindVertexArray(0);

  glBindBuffer(GL_TEXTURE_BUFFER, shape_buffer_);
  glBufferData(GL_TEXTURE_BUFFER, 6 * static_cast<GLsizeiptr>(plane_stride_) * sizeof(float),
               nullptr, GL_STREAM_DRAW);
  glBindTexture(GL_TEXTURE_BUFFER, shape_texture_);
  glTexBuffer(GL_TEXTURE_BUFFER, GL_R32F, shape_buffer_);
  glBindBuffer(GL_TEXTURE_BUFFER, 0);
}

void Renderer::upload_key_textures(int width, int height,
                                   std::span<const std::uint8_t* const> images,
                                   std::span<const Vec2f> corner_uvs) {
  if (corner_uvs.size() != 3 * triangles_.size()) {
    throw InputError(fmt::format("{} corner UVs for {} triangles (expected {})", corner_uvs.size(),
                                 triangles_.size(), 3 * triangles_.size()));
  }
  if (images.empty() || width <= 0 || height <= 0) {
    throw InputError(fmt::format("no key textures to upload ({} images of {}x{})", images.size(),
                                 width, height));
  }
  GLint max_layers = 0, max_size = 0;
  glGetIntegerv(GL_MAX_ARRAY_TEXTURE_LAYERS, &max_layers);
  glGetIntegerv(GL_MAX_TEXTURE_SIZE, &max_size);
  if (static_cast<GLint>(images.size()) > max_layers || width > max_size || height > max_size) {
    throw ConfigError(fmt::format("{} key textures of {}x{} exceed this GPU's texture arrays "
                                  "({} layers of at most {}x{})",
                                  images.size(), width, height, max_layers, max_size, max_size));
  }
  // One draw vertex per distinct (vertex, UV) pair: vertices on chart seams are duplicated.
  std::map<std::pair<int, std::pair<float, float>>, GLuint> ids;
  std::vector<DrawVertex> vertices;
  std::vector<GLuint> indices;
  indices.reserve(3 * triangles_.size());
  for (std::size_t f = 0; f < triangles_.size(); ++f) {
    for (int c = 0; c < 3; ++c) {
      const Vec2f& uv = corner_uvs[3 * f + c];
      const auto key = std::make_pair(triangles_[f][c], std::make_pair(uv.x(), uv.y()));
      const auto [it, added] = ids.emplace(key, static_cast<GLuint>(vertices.size()));
      if (added) vertices.push_back({triangles_[f][c], uv.x(), uv.y()});
      indices.push_back(it->second);
    }
  }
  glBindVertexArray(character_vao_);
  glBindBuffer(GL_ARRAY_BUFFER, character_vbo_);
  glBufferData(GL_ARRAY_BUFFER, vertices.size() * sizeof(DrawVertex), vertices.data(),
               GL_STATIC_DRAW);
  glBindBuffer(GL_ELEMENT_ARRAY_BUFFER, character_ibo_);
  glBufferData(GL_ELEMENT_ARRAY_BUFFER, indices.size() * sizeof(GLuint), indices.data(),
               GL_STATIC_DRAW);
  glBindVertexArray(0);

  if (!key_texture_) glGenTextures(1, &key_texture_);
  glBindTexture(GL_TEXTURE_2D_ARRAY, key_texture_);
  glPixelStorei(GL_UNPACK_ALIGNMENT, 1);
  glTexImage3D(GL_TEXTURE_2D_ARRAY, 0, GL_RGB8, width, height,
               static_cast<GLsizei>(images.size()), 0, GL_BGR, GL_UNSIGNED_BYTE, nullptr);
  for (std::size_t layer = 0; layer < images.size(); ++layer) {
    glTexSubImage3D(GL_TEXTURE_2D_ARRAY, 0, 0, 0, static_cast<GLint>(layer), width, height, 1,
                    GL_BGR, GL_UNSIGNED_BYTE, images[layer]);
  }
  glGenerateMipmap(GL_TEXTURE_2D_ARRAY);
  glTexParameteri(GL_TEXTURE_2D_ARRAY, GL_TEXTURE_MIN_FILTER, GL_LINEAR_MIPMAP_LINEAR);
  glTexParameteri(GL_TEXTURE_2D_ARRAY, GL_TEXTURE_MAG_FILTER, GL_LINEAR);
  glTexParameteri(GL_TEXTURE_2D_ARRAY, GL_TEXTURE_WRAP_S, GL_CLAMP_TO_EDGE);
  glTexParameteri(GL_TEXTURE_2D_ARRAY, GL_TEXTURE_WRAP_T, GL_CLAMP_TO_EDGE);
  glBindTexture(GL_TEXTURE_2D_ARRAY, 0);
  if (glGetError() == GL_OUT_OF_MEMORY) {
    throw ConfigError(fmt::format("out of GPU memory for {} key textures of {}x{}", images.size(),
                                  width, height));
  }
  num_indices_ = static_cast<int>(indices.size());
  num_layers_ = static_cast<int>(images.size());
  blend_count_ = 0;
}

void Renderer::set_key_blend(std::span<const int> layers, std::span<const float> weights) {
  blend_count_ = static_cast<int>(std::min({layers.size(), weights.size(),
                                            static_cast<std::size_t>(kMaxKeyLayers)}));
  for (int k = 0; k < blend_count_; ++k) {
    layers_[k] = std::clamp(layers[k], 0, std::max(num_layers_ - 1, 0));
    weights_[k] = weights[k];
  }
}

void Renderer::update_character(const CharacterFrame& frame) {
  const std::size_t plane_bytes = 3 * static_cast<std::size_t>(plane_stride_) * sizeof(float);
  glBindBuffer(GL_TEXTURE_BUFFER, shape_buffer_);
  glBufferSubData(GL_TEXTURE_BUFFER, 0, plane_bytes, frame.positions.data.data());
  glBufferSubData(GL_TEXTURE_BUFFER, plane_bytes, plane_bytes, frame.normals.data.data());
  glBindBuffer(GL_TEXTURE_BUFFER, 0);
  root_ = frame.root;
}

void Renderer::begin_frame(int width, int height) {
  glViewport(0, 0, width, height);
  glClearColor(0.62f, 0.68f, 0.74f, 1);
  glClear(GL_COLOR_BUFFER_BIT | GL_DEPTH_BUFFER_BIT);
  glEnable(GL_DEPTH_TEST);
  glDepthFunc(GL_LEQUAL);
  glDisable(GL_CULL_FACE);
}

void Renderer::draw_ground(const Mat4f& view_projection, float centre_x, float centre_y) {
  constexpr int kHalf = 25;  // [m] the grid reaches this far from its centre
  const float cx = std::round(centre_x), cy = std::round(centre_y);
  grid_.clear();
  const LineVertex ground[] = {{cx - kHalf, cy - kHalf, 0, 0.47f, 0.5f, 0.46f},
                               {cx + kHalf, cy - kHalf, 0, 0.47f, 0.5f, 0.46f},
                               {cx + kHalf, cy + kHalf, 0, 0.47f, 0.5f, 0.46f},
                               {cx - kHalf, cy + kHalf, 0, 0.47f, 0.5f, 0.46f}};
  grid_.insert(grid_.end(), {ground[0], ground[1], ground[2], ground[0], ground[2], ground[3]});
  // Polygon offset pushes the ground back so the grid lines on it win the depth test.
  glEnable(GL_POLYGON_OFFSET_FILL);
  glPolygonOffset(1, 1);
  draw_primitives(view_projection, grid_, GL_TRIANGLES, 1);
  glDisable(GL_POLYGON_OFFSET_FILL);
  grid_.clear();
  for (int k = -kHalf; k <= kHalf; ++k) {
    const float x = cx + k, y = cy + k;
    // Every 5th line brighter, the world axes red (x) and green (y).
    const bool major = static_cast<int>(std::lround(x)) % 5 == 0;
    const float g = major ? 0.66f : 0.56f;
    const bool y_axis = std::lround(x) == 0, x_axis = std::lround(y) == 0;
    const float ry = y_axis ? 0.3f : g, gy = y_axis ? 0.75f : g, by = y_axis ? 0.3f : g;
    grid_.push_back({x, cy - kHalf, 0, ry, gy, by});
    grid_.push_back({x, cy + kHalf, 0, ry, gy, by});
    const bool major_y = static_cast<int>(std::lround(y)) % 5 == 0;
    const float h = major_y ? 0.66f : 0.56f;
    const float rx = x_axis ? 0.8f : h, gx = x_axis ? 0.3f : h, bx = x_axis ? 0.3f : h;
    grid_.push_back({cx - kHalf, y, 0, rx, gx, bx});
    grid_.push_back({cx + kHalf, y, 0, rx, gx, bx});
  }
  draw_primitives(view_projection, grid_, GL_LINES, 1);
}

void Renderer::draw_character(const Mat4f& view_projection, const Eigen::Vector3f& eye) {
  if (num_indices_ == 0) return;
  glUseProgram(character_program_);
  glUniformMatrix4fv(uniform(character_program_, "u_view_projection"), 1, GL_FALSE,
                     view_projection.data());
  glUniform3f(uniform(character_program_, "u_root"), static_cast<float>(root_.x),
              static_cast<float>(root_.y), static_cast<float>(root_.heading));
  glUniform1i(uniform(character_program_, "u_stride"), plane_stride_);
  glUniform3f(uniform(character_program_, "u_eye"), eye.x(), eye.y(), eye.z());
  glUniform3f(uniform(character_program_, "u_albedo"), 0.78f, 0.62f, 0.5f);
  glActiveTexture(GL_TEXTURE0);
  glBindTexture(GL_TEXTURE_BUFFER, shape_texture_);
  glUniform1i(uniform(character_program_, "u_shape"), 0);
  const int count = num_layers_ > 0 ? blend_count_ : 0;
  glActiveTexture(GL_TEXTURE1);
  glBindTexture(GL_TEXTURE_2D_ARRAY, key_texture_);
  glUniform1i(uniform(character_program_, "u_keys"), 1);
  glUniform1i(uniform(character_program_, "u_count"), count);
  if (count > 0) {
    glUniform1iv(uniform(character_program_, "u_layers"), count, layers_.data());
    glUniform1fv(uniform(character_program_, "u_weights"), count, weights_.data());
  }
  glBindVertexArray(character_vao_);
  glDrawElements(GL_TRIANGLES, num_indices_, GL_UNSIGNED_INT, nullptr);
  glBindVertexArray(0);
  glActiveTexture(GL_TEXTURE1);
  glBindTexture(GL_TEXTURE_2D_ARRAY, 0);
  glActiveTexture(GL_TEXTURE0);
  glBindTexture(GL_TEXTURE_BUFFER, 0);
}

void Renderer::draw_lines(const Mat4f& view_projection, std::span<const LineVertex> vertices,
                          bool strip) {
  draw_primitives(view_projection, vertices, strip ? GL_LINE_STRIP : GL_LINES, 1);
}

void Renderer::draw_points(const Mat4f& view_projection, std::span<const LineVertex> vertices,
                           float size_pixels) {
  draw_primitives(view_projection, vertices, GL_POINTS, size_pixels);
}

void Renderer::draw_primitives(const Mat4f& view_projection, std::span<const LineVertex> vertices,
                               unsigned mode, float point_size) {
  if (vertices.empty()) return;
  glUseProgram(line_program_);
  glUniformMatrix4fv(uniform(line_program_, "u_view_projection"), 1, GL_FALSE,
                     view_projection.data());
  glUniform1f(uniform(line_program_, "u_point_size"), point_size);
  glBindVertexArray(line_vao_);
  glBindBuffer(GL_ARRAY_BUFFER, line_vbo_);
  glBufferData(GL_ARRAY_BUFFER, vertices.size_bytes(), vertices.data(), GL_STREAM_DRAW);
  glDrawArrays(mode, 0, static_cast<GLsizei>(vertices.size()));
  glBindVertexArray(0);
}

}  // namespace fourd::viewer
