#pragma once
// The virtual studio: a camera rig around the capture volume and an Embree renderer that
// draws the textured performer over a backdrop (a chroma screen and floor, green by default,
// or a furnished room) with soft shadows, anti-aliasing, lens distortion and sensor noise.
#include <cstdint>
#include <memory>
#include <opencv2/core.hpp>
#include <optional>
#include <string>
#include <vector>

#include "pipeline/core/camera.h"
#include "pipeline/core/config.h"
#include "pipeline/core/mesh.h"

namespace fourd::synth {

// The options are the members visit() lists, with their help; the others are tuned values,
// not options (docs/synth.md, "Advanced").
struct RigOptions {
  int count = 8;
  double radius = 3.5;
  double height = 1.6;
  double target_height = 0.9;  // all cameras look at (0, 0, target_height) [m]: about the
                               // middle of a 1.75 m performer
  int width = 640;
  int height_px = 480;
  double focal_px = 560;
  double k1 = 0, k2 = 0;
  double p1 = 0, p2 = 0;       // tangential distortion (the sample studio's lenses have
                               // radial distortion only)
  double start_angle = 0;      // angle of camera 0 on the circle [deg]

  template <class V>
  void visit(V& v) {
    v("count", count, "number of cameras, equally spaced on a circle", Range{1, 256});
    v("radius", radius, "circle radius [m]", Range{0.5, 100});
    v("height", height, "camera centre height above the floor [m]", Range{0, 20});
    v("width", width, "image width [px]", Range{16, 16384});
    v("height_px", height_px, "image height [px]", Range{16, 16384});
    v("focal_px", focal_px, "focal length [px]", Range{1, 100000});
    v("k1", k1, "radial distortion k1", Range{-1, 1});
    v("k2", k2, "radial distortion k2", Range{-1, 1});
  }
};

// Cameras named cam00, cam01, ... on the circle, all looking at the volume centre.
std::vector<Camera> make_rig(const RigOptions& options);

// Options: the members visit() lists; the lighting and the backdrop's shape are tuned values,
// not options (docs/synth.md, "Advanced").
struct StudioOptions {
  int samples_per_pixel = 4;
  double noise_sigma = 2.0;
  double light_elevation = 60;       // key light elevation [deg]
  double light_azimuth = 30;         // key light azimuth [deg]
  double ambient = 0.35;             // ambient light fraction
  double wall_distance = 4.5;        // green backdrop cylinder radius [m] (behind the cameras)
  double backdrop_variation = 0.08;  // relative low-frequency brightness variation of the screen
  int shadow_samples = 32;           // light samples per shaded point (soft shadows; 1 = hard)
  double light_radius = 4;           // angular radius of the key light [deg] (penumbra width)
  std::string backdrop = "green";

  template <class V>
  void visit(V& v) {
    v("samples_per_pixel", samples_per_pixel,
      "anti-aliasing samples on edge pixels (1: none)", Range{1, 64});
    v("noise_sigma", noise_sigma, "sensor noise std-dev [8-bit grey levels]", Range{0, 50});
    v("backdrop", backdrop,
      "what surrounds the volume: green | blue | #RRGGBB (a chroma screen and floor of that "
      "colour) | room (a furnished room, no screen: synth also writes plates/ of the empty room "
      "and lets the lights flicker a little)");
  }
  void check() const;
  bool room() const { return backdrop == "room"; }
};

// The key colour of a chroma studio's screen (RGB in [0, 1]), which a costume department keeps
// out of the performer's wardrobe; nullopt for the room, which has no key colour.
std::optional<Eigen::Vector3d> studio_key_color(const StudioOptions& options);

// Work counts of one render, for logs and benchmarks.
struct RenderStats {
  std::int64_t camera_rays = 0;          // rays from the camera (centre + anti-aliasing samples)
  std::int64_t shadow_rays = 0;          // occlusion rays traced by Embree towards the key light
  std::int64_t supersampled_pixels = 0;  // edge pixels that got samples_per_pixel rays
};

struct RenderedView {
  cv::Mat image;       // CV_8UC3 BGR, what the camera records (with noise)
  cv::Mat silhouette;  // CV_8UC1, 255 where the performer covers the pixel centre, else 0
  cv::Mat depth;       // CV_32FC1, camera z of the performer at the pixel centre, 0 elsewhere
  RenderStats stats;
};

// Renders the performer for one frame. Build once per frame (the BVH of the posed mesh), then
// render every camera; thread-safe across cameras.
class StudioRenderer {
 public:
  explicit StudioRenderer(const StudioOptions& options);
  ~StudioRenderer();
  StudioRenderer(const StudioRenderer&) = delete;
  StudioRenderer& operator=(const StudioRenderer&) = delete;

  // `mesh` must have per-vertex (or per-corner) UVs addressing `texture` (CV_8UC3, BGR).
  // UVs follow the OBJ convention: (0,0) is the bottom-left corner of the image, v up.
  // Uses mesh.normals for smooth shading when present, else computes vertex normals.
  // Throws InputError when the mesh or the texture is unusable.
  void set_performer(const Mesh& mesh, const cv::Mat& texture);
  // `noise_seed` makes the sensor noise deterministic; `gain` scales all light (flicker).
  // Before set_performer() it renders the empty studio (background plates).
  RenderedView render(const Camera& camera, std::uint64_t noise_seed, float gain = 1.0f) const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace fourd::synth
