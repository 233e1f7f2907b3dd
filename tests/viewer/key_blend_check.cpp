// Checks, in a real OpenGL 3.3 context (run under xvfb-run by viewer_test.sh), that the viewer's
// renderer blends key textures on the GPU with the weights it is given: a quad filling the view,
// textured with a red and a blue layer, drawn at weights (0.25, 0.75), (0, 1) and without
// textures. Exit 0 when every check holds, 1 otherwise.
#include <epoxy/gl.h>
#define GLFW_INCLUDE_NONE
#include <GLFW/glfw3.h>

#include <array>
#include <cstdio>
#include <vector>

#include "runtime/blend.h"
#include "runtime/viewer/renderer.h"

namespace {

using namespace fourd;
using namespace fourd::viewer;

std::array<int, 3> centre_rgb(int size) {
  std::array<unsigned char, 3> p{};
  glPixelStorei(GL_PACK_ALIGNMENT, 1);
  glReadPixels(size / 2, size / 2, 1, 1, GL_RGB, GL_UNSIGNED_BYTE, p.data());
  return {p[0], p[1], p[2]};
}

}  // namespace

int main() {
  constexpr int kSize = 64;
  if (!glfwInit()) {
    std::fprintf(stderr, "key_blend_check: no display\n");
    return 1;
  }
  glfwWindowHint(GLFW_CONTEXT_VERSION_MAJOR, 3);
  glfwWindowHint(GLFW_CONTEXT_VERSION_MINOR, 3);
  glfwWindowHint(GLFW_OPENGL_PROFILE, GLFW_OPENGL_CORE_PROFILE);
  glfwWindowHint(GLFW_OPENGL_FORWARD_COMPAT, GLFW_TRUE);
  GLFWwindow* window = glfwCreateWindow(kSize, kSize, "key_blend_check", nullptr, nullptr);
  if (!window) {
    std::fprintf(stderr, "key_blend_check: no OpenGL 3.3 core context\n");
    glfwTerminate();
    return 1;
  }
  glfwMakeContextCurrent(window);
  int failures = 0;
  {
    Renderer renderer;
    // A quad in the plane x = 0, facing -x, much larger than the view.
    const std::vector<Tri> triangles{Tri(0, 1, 2), Tri(0, 2, 3)};
    renderer.set_mesh(triangles, 4);
    CharacterFrame frame;
    const int stride = blend_plane_stride(4);
    for (BlendedFrame* f : {&frame.positions, &frame.normals}) {
      f->num_vertices = 4;
      f->plane_stride = stride;
      f->data.assign(3 * stride, 0.0f);
    }
    const float y[4] = {-5, 5, 5, -5}, z[4] = {-5, -5, 5, 5};
    for (int v = 0; v < 4; ++v) {
      frame.positions.data[stride + v] = y[v];
      frame.positions.data[2 * stride + v] = z[v];
      frame.normals.data[v] = -1;
    }
    renderer.update_character(frame);
    // Layer 0 red, layer 1 blue (BGR bytes, 2 x 2 texels).
    std::vector<std::uint8_t> red(12), blue(12);
    for (int t = 0; t < 4; ++t) {
      red[3 * t + 2] = 255;
      blue[3 * t] = 255;
    }
    const std::vector<const std::uint8_t*> images{red.data(), blue.data()};
    std::vector<Vec2f> uvs(6, Vec2f(0.5f, 0.5f));
    renderer.upload_key_textures(2, 2, images, uvs);

    OrbitCamera camera;
    camera.mode = CameraMode::kOrbit;
    camera.target = {0, 0, 0};
    camera.yaw = 0;
    camera.pitch = 0;
    camera.distance = 2;
    const Mat4f vp = camera.projection(1) * camera.view();
    auto draw = [&](std::vector<int> layers, std::vector<float> weights) {
      renderer.set_key_blend(layers, weights);
      renderer.begin_frame(kSize, kSize);
      renderer.draw_character(vp, camera.eye());
      glFinish();
      return centre_rgb(kSize);
    };
    auto check = [&](bool ok, const char* what, const std::array<int, 3>& rgb) {
      std::printf("%s: %s (rgb %d %d %d)\n", ok ? "ok" : "FAILED", what, rgb[0], rgb[1], rgb[2]);
      failures += ok ? 0 : 1;
    };
    const std::array<int, 3> mixed = draw({0, 1}, {0.25f, 0.75f});
    check(mixed[1] <= 2 && mixed[0] > 20 && mixed[2] > 2.7 * mixed[0] && mixed[2] < 3.3 * mixed[0],
          "0.25 red + 0.75 blue blends to blue = 3 x red", mixed);
    const std::array<int, 3> only_blue = draw({1}, {1.0f});
    check(only_blue[0] <= 2 && only_blue[1] <= 2 && only_blue[2] > 100, "layer 1 alone is blue",
          only_blue);
    const std::array<int, 3> shaded = draw({}, {});
    check(shaded[0] > shaded[2] && shaded[1] > 10, "no layers: the shading colour", shaded);
    if (glGetError() != GL_NO_ERROR) {
      std::printf("FAILED: OpenGL error\n");
      ++failures;
    }
  }
  glfwDestroyWindow(window);
  glfwTerminate();
  return failures == 0 ? 0 : 1;
}
