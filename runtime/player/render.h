#pragma once
// Headless rendering for fourd-play (`--render DIR`): every played frame of the character drawn
// by Embree ray casting (pipeline/render/textured_render.h) into a PNG, on a checkered ground
// plane with the character's shadow. With textures in the asset the character shows its
// captured appearance, the key textures blended with the frame's weights
// (CharacterFrame::textures, blend_texture_image); without, it is shaded grey.
//
// Cameras: `follow`, an orbit camera looking at the root (at half the character's height) from
// `distance` metres, `elevation` degrees above the ground, at world azimuth `azimuth` degrees
// (counter-clockwise from +x), circling at `orbit` degrees per second; or `studio:N`, camera N
// (0-based, in the model's order) of a COLMAP calibration folder, for comparison with the
// capture. With `mp4` set, ffmpeg (when on PATH) encodes the PNGs into a video.
//
// Writes DIR/frame_NNNNN.png (NNNNN the played frame) and DIR/render.json: camera, image size,
// textured or shaded, per frame the fraction of pixels the character covers and its pixel
// centroid, and the video's outcome.
#include <filesystem>
#include <memory>
#include <string>
#include <vector>

#include "pipeline/core/camera.h"
#include "runtime/player.h"

namespace fourd {

struct RenderOptions {
  std::filesystem::path dir;          // where the PNGs go
  std::string camera = "follow";      // follow | studio:N
  std::filesystem::path calibration;  // COLMAP model folder, for studio:N
  int width = 0, height = 0;          // image size; 0: 640 x 480 (follow), the camera's (studio)
  double distance = 4.0;              // follow: from the look-at point [m]
  double elevation = 12;              // follow: above the horizontal [deg]
  double azimuth = -60;               // follow: world direction to the camera [deg]
  double orbit = 0;                   // follow: turn rate of the camera about the root [deg/s]
  double field_of_view = 50;          // follow: horizontal [deg]
  int every = 1;                      // render every n-th frame
  std::filesystem::path mp4;          // empty: no video
  // Throws UsageError naming the option.
  void check() const;
};

struct RenderedFrameStats {
  int frame = 0;
  double foreground = 0;  // fraction of the image the character covers
  double centroid_x = 0, centroid_y = 0;  // its pixel centroid, in image widths / heights
};

class FrameRenderer : public FrameObserver {
 public:
  // Reads the calibration for studio:N. Throws UsageError for a bad camera choice, InputError
  // naming the folder for a calibration without camera N.
  FrameRenderer(const MotionGraph& graph, const RenderOptions& options);
  ~FrameRenderer() override;

  void on_frame(int index, double time, const Character& character) override;
  // Encodes the video when asked (a missing ffmpeg is a warning: the PNGs stay) and writes
  // render.json. `fps`: the played frame rate.
  void finish(double fps);

  bool textured() const;
  const Camera& camera() const;  // the last frame's
  const std::vector<RenderedFrameStats>& stats() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace fourd
