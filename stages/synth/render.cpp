#include "stages/synth/render.h"

#include <embree3/rtcore.h>
#include <fmt/format.h>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <cctype>
#include <cmath>
#include <limits>
#include <numbers>
#include <opencv2/imgproc.hpp>
#include <optional>

#include "pipeline/core/error.h"

namespace fourd::synth {

std::vector<Camera> make_rig(const RigOptions& options) {
  if (options.count < 1) throw ConfigError(fmt::format("rig: count {} < 1", options.count));
  if (options.width < 1 || options.height_px < 1 || !(options.focal_px > 0)) {
    throw ConfigError(fmt::format("rig: bad image size {}x{} or focal length {}", options.width,
                                  options.height_px, options.focal_px));
  }
  const Eigen::Vector3d target(0, 0, options.target_height);
  std::vector<Camera> cameras;
  cameras.reserve(options.count);
  for (int i = 0; i < options.count; ++i) {
    const double angle =
        (options.start_angle + 360.0 * i / options.count) * std::numbers::pi / 180.0;
    const Eigen::Vector3d eye(options.radius * std::cos(angle), options.radius * std::sin(angle),
                              options.height);
    Camera camera;
    camera.name = fmt::format("cam{:02d}", i);
    Intrinsics& k = camera.intrinsics;
    k.width = options.width;
    k.height = options.height_px;
    k.fx = k.fy = options.focal_px;
    k.cx = options.width / 2.0;
    k.cy = options.height_px / 2.0;
    k.k1 = options.k1;
    k.k2 = options.k2;
    k.p1 = options.p1;
    k.p2 = options.p2;
    camera.camera_from_world = look_at(eye, target, Eigen::Vector3d::UnitZ());
    cameras.push_back(std::move(camera));
  }
  return cameras;
}

namespace {

// ---------------------------------------------------------------------------------------------
// Counter-based random numbers: every value is a pure function of its inputs, so images do not
// depend on thread scheduling or on the order pixels are visited.

std::uint64_t mix64(std::uint64_t x) {  // splitmix64 finaliser
  x += 0x9e3779b97f4a7c15ull;
  x = (x ^ (x >> 30)) * 0xbf58476d1ce4e5b9ull;
  x = (x ^ (x >> 27)) * 0x94d049bb133111ebull;
  return x ^ (x >> 31);
}

std::uint64_t hash3(std::uint64_t a, std::uint64_t b, std::uint64_t c) {
  return mix64(mix64(mix64(a) ^ b) ^ c);
}

// Uniform in [0, 1) from the top 24 bits of `bits`.
float to_unit(std::uint64_t bits) { return static_cast<float>(bits >> 40) * (1.0f / 16777216.0f); }

double radical_inverse2(std::uint32_t i) {
  i = (i << 16) | (i >> 16);
  i = ((i & 0x00ff00ffu) << 8) | ((i & 0xff00ff00u) >> 8);
  i = ((i & 0x0f0f0f0fu) << 4) | ((i & 0xf0f0f0f0u) >> 4);
  i = ((i & 0x33333333u) << 2) | ((i & 0xccccccccu) >> 2);
  i = ((i & 0x55555555u) << 1) | ((i & 0xaaaaaaaau) >> 1);
  return i * (1.0 / 4294967296.0);
}

// ---------------------------------------------------------------------------------------------
// Procedural studio textures. Both are functions of world position, so every camera sees the
// same floor pattern (stereo can match it) and the same backdrop.

// Smooth value noise in [-1, 1] on the integer lattice.
float value_noise(float x, float y, std::uint64_t salt) {
  const float fx = std::floor(x), fy = std::floor(y);
  const auto ix = static_cast<std::int64_t>(fx), iy = static_cast<std::int64_t>(fy);
  auto lattice = [&](std::int64_t i, std::int64_t j) {
    return 2.0f *
               to_unit(hash3(salt, static_cast<std::uint64_t>(i), static_cast<std::uint64_t>(j))) -
           1.0f;
  };
  float tx = x - fx, ty = y - fy;
  tx = tx * tx * (3 - 2 * tx);
  ty = ty * ty * (3 - 2 * ty);
  const float a = lattice(ix, iy), b = lattice(ix + 1, iy);
  const float c = lattice(ix, iy + 1), d = lattice(ix + 1, iy + 1);
  return (a + (b - a) * tx) + ((c + (d - c) * tx) - (a + (b - a) * tx)) * ty;
}

// Mottling of a painted surface at several scales (a factor near 1). Octaves finer than the
// pixel footprint fade out, which keeps the far floor from aliasing.
float mottling(double x, double y, float footprint_m) {
  struct Octave {
    float wavelength, amplitude;
  };
  static constexpr std::array<Octave, 4> kOctaves{
      {{0.9f, 0.06f}, {0.25f, 0.04f}, {0.07f, 0.035f}, {0.025f, 0.03f}}};
  float brightness = 1.0f;
  std::uint64_t salt = 17;
  for (const Octave& o : kOctaves) {
    const float fade =
        std::clamp((o.wavelength / std::max(footprint_m, 1e-6f) - 2.0f) / 2.0f, 0.0f, 1.0f);
    if (fade > 0) {
      brightness += fade * o.amplitude *
                    value_noise(static_cast<float>(x / o.wavelength),
                                static_cast<float>(y / o.wavelength), salt);
    }
    ++salt;
  }
  return brightness;
}

// Chroma studio floor (BGR albedo `paint`), as volumetric-capture stages paint their floors,
// mottled; the performer's shadow falls on it.
Eigen::Vector3f floor_albedo(const Eigen::Vector3f& paint, double x, double y, float footprint_m) {
  return paint * mottling(x, y, footprint_m);
}

// Chroma backdrop (BGR `paint`, already lit by its own even screen lights) with a low-frequency
// brightness variation of relative amplitude `variation`.
Eigen::Vector3f backdrop_color(const Eigen::Vector3f& paint, double azimuth, double z,
                               double variation) {
  const double s = 0.45 * std::sin(2 * azimuth + 0.7) +
                   0.35 * std::sin(3 * azimuth - 1.1 + 0.8 * z) + 0.2 * std::cos(1.7 * z + 0.4);
  return paint * static_cast<float>(0.92 * (1.0 + variation * s));
}

// Screen and floor paints (BGR in [0, 1]) of the chroma studios. Green: the studio of the
// default sample. Blue: the chroma blue of blue-screen paint (sRGB about 25, 70, 185), the floor
// a little lighter and less saturated as painted floors are.
struct ScreenPaint {
  Eigen::Vector3f wall, floor;
};
ScreenPaint screen_paint(const std::string& backdrop) {
  if (backdrop == "green") {
    return {{60.f / 255, 170.f / 255, 40.f / 255}, {70.f / 255, 175.f / 255, 60.f / 255}};
  }
  if (backdrop == "blue") {
    return {{185.f / 255, 70.f / 255, 25.f / 255}, {180.f / 255, 82.f / 255, 38.f / 255}};
  }
  // "#RRGGBB", checked by StudioOptions::check(): screen and floor of that paint.
  const unsigned long rgb = std::stoul(backdrop.substr(1), nullptr, 16);
  const Eigen::Vector3f paint((rgb & 0xff) / 255.f, ((rgb >> 8) & 0xff) / 255.f,
                              ((rgb >> 16) & 0xff) / 255.f);
  return {paint, paint};
}

// ---------------------------------------------------------------------------------------------
}  // namespace

std::optional<Eigen::Vector3d> studio_key_color(const StudioOptions& options) {
  if (options.room()) return std::nullopt;
  const Eigen::Vector3f bgr = screen_paint(options.backdrop).wall;
  return Eigen::Vector3d(bgr.z(), bgr.y(), bgr.x());
}

namespace {

// The furnished room (backdrop "room"): painted walls with a skirting board and posters, a tiled
// floor with a rug, and furniture (cupboards, shelves, boxes) along the walls, some of it
// coloured like the performer's clothes and skin, so that no colour tells the performer apart.

Eigen::Vector3f bgr(int r, int g, int b) { return Eigen::Vector3f(b / 255.f, g / 255.f, r / 255.f); }

// One piece of furniture: a box facing the volume's centre, at `azimuth` [rad], from `inner` to
// `outer` [m] from the centre, `half_width` [m] either side, from the floor to `height` [m].
struct Furniture {
  float azimuth, inner, outer, half_width, height;
  Eigen::Vector3f color;
  int style;  // 0 plain, 1 shelves with books, 2 drawers
};

// Furniture stands within kFurnitureDepth of the wall: cameras stand nearer the centre (the
// default rig at 3.5 m, the wall at 4.5 m), so no piece ever hides the performer from a camera.
constexpr float kFurnitureDepth = 0.62f;

std::vector<Furniture> room_furniture(float wall) {
  struct Piece {
    float azimuth_deg, depth, width, height;
    Eigen::Vector3f color;
    int style;
  };
  // Colours: wood, white, and some of the clothing palette (red, denim, skin, dark grey).
  const std::vector<Piece> pieces = {
      {8, 0.45f, 1.3f, 0.85f, bgr(200, 40, 40), 0},    {40, 0.35f, 0.9f, 1.9f, bgr(120, 85, 55), 1},
      {75, 0.55f, 1.1f, 0.75f, bgr(45, 65, 115), 2},   {110, 0.4f, 0.7f, 1.4f, bgr(230, 228, 222), 1},
      {148, 0.6f, 1.4f, 0.5f, bgr(225, 180, 145), 0},  {185, 0.35f, 1.0f, 2.1f, bgr(95, 70, 50), 1},
      {222, 0.5f, 0.8f, 1.1f, bgr(32, 32, 36), 2},     {255, 0.45f, 1.2f, 0.9f, bgr(140, 140, 148), 0},
      {290, 0.3f, 0.9f, 1.7f, bgr(185, 158, 112), 1},  {322, 0.55f, 0.9f, 0.6f, bgr(120, 50, 150), 0},
      {345, 0.3f, 0.5f, 1.2f, bgr(40, 80, 190), 2},
  };
  std::vector<Furniture> out;
  for (const Piece& p : pieces) {
    const float outer = wall - 0.02f;
    out.push_back({p.azimuth_deg * std::numbers::pi_v<float> / 180, outer - std::min(p.depth, kFurnitureDepth),
                   outer, 0.5f * p.width, p.height, p.color, p.style});
  }
  return out;
}

// Ray (o, d) against a piece of furniture: the entry distance and the outward face normal.
bool hit_furniture(const Furniture& f, const Eigen::Vector3d& o, const Eigen::Vector3d& d,
                   double* t_hit, Eigen::Vector3d* normal) {
  // The box's frame: x towards the wall, y along it, z up.
  const double c = std::cos(f.azimuth), s = std::sin(f.azimuth);
  const Eigen::Vector3d lo(f.inner, -f.half_width, 0), hi(f.outer, f.half_width, f.height);
  const Eigen::Vector3d lo_o(c * o.x() + s * o.y(), -s * o.x() + c * o.y(), o.z());
  const Eigen::Vector3d ld(c * d.x() + s * d.y(), -s * d.x() + c * d.y(), d.z());
  double t0 = 1e-6, t1 = std::numeric_limits<double>::infinity();
  int axis = -1;
  double sign = 0;
  for (int a = 0; a < 3; ++a) {
    if (std::abs(ld[a]) < 1e-12) {
      if (lo_o[a] < lo[a] || lo_o[a] > hi[a]) return false;
      continue;
    }
    double near = (lo[a] - lo_o[a]) / ld[a], far = (hi[a] - lo_o[a]) / ld[a];
    double face = -1;
    if (near > far) {
      std::swap(near, far);
      face = 1;
    }
    if (near > t0) {
      t0 = near;
      axis = a;
      sign = face;
    }
    t1 = std::min(t1, far);
    if (t0 > t1) return false;
  }
  if (axis < 0) return false;  // the ray starts inside the box
  Eigen::Vector3d n_local = Eigen::Vector3d::Zero();
  n_local[axis] = sign;
  *normal = Eigen::Vector3d(c * n_local.x() - s * n_local.y(), s * n_local.x() + c * n_local.y(),
                            n_local.z());
  *t_hit = t0;
  return true;
}

// Albedo of a piece of furniture at the world point p.
Eigen::Vector3f furniture_albedo(const Furniture& f, const Eigen::Vector3d& p, float footprint) {
  const double c = std::cos(f.azimuth), s = std::sin(f.azimuth);
  const double along = -s * p.x() + c * p.y();  // across its front [m]
  const float grain = mottling(along * 3.1, p.z() * 3.1, footprint);
  Eigen::Vector3f color = f.color * grain;
  if (f.style == 1) {  // shelves every 0.38 m, books of many colours between them
    const double shelf = std::fmod(p.z(), 0.38);
    if (shelf < 0.03) return f.color * 0.7f * grain;
    const double book = std::floor((along + 2.0) / 0.045);
    const std::uint64_t h = hash3(91, static_cast<std::uint64_t>(book + 1000),
                                  static_cast<std::uint64_t>(p.z() / 0.38));
    static const std::array<Eigen::Vector3f, 6> books = {
        bgr(200, 40, 40), bgr(40, 80, 190), bgr(230, 228, 222),
        bgr(225, 190, 40), bgr(32, 32, 36), bgr(220, 110, 150)};
    const float top = 0.2f + 0.14f * to_unit(mix64(h));  // book height above the shelf
    if (shelf < top) return books[h % books.size()] * grain;
    return f.color * 0.45f;  // the back of the shelf, in its own shade
  }
  if (f.style == 2) {  // drawers: dark gaps every 0.25 m and a handle
    const double drawer = std::fmod(p.z(), 0.25);
    if (drawer < 0.015) return color * 0.35f;
    if (drawer > 0.11 && drawer < 0.14 && std::abs(std::fmod(std::abs(along) + 1.0, 0.6) - 0.3) < 0.05) {
      return bgr(200, 200, 205);
    }
  }
  return color;
}

// The room's wall (a cylinder around the volume) at azimuth a and height z: painted plaster,
// a skirting board, wallpaper in some sectors and posters.
Eigen::Vector3f room_wall_albedo(double a, double z, double wall, float footprint) {
  const double arc = a * wall;  // distance along the wall [m]
  if (z < 0.12) return bgr(95, 70, 50) * mottling(arc * 4, z * 4, footprint);
  // Posters: rectangles of strong colour.
  struct Poster {
    float azimuth_deg, width, bottom, top;
    Eigen::Vector3f color, stripe;
  };
  static const std::array<Poster, 5> posters = {{
      {22, 0.7f, 1.3f, 2.1f, bgr(200, 40, 40), bgr(230, 228, 222)},
      {130, 0.9f, 1.5f, 2.2f, bgr(40, 80, 190), bgr(225, 190, 40)},
      {200, 0.6f, 1.2f, 1.9f, bgr(225, 180, 145), bgr(125, 25, 40)},
      {272, 1.0f, 1.4f, 2.0f, bgr(30, 40, 95), bgr(220, 110, 150)},
      {335, 0.8f, 1.6f, 2.3f, bgr(120, 170, 220), bgr(40, 38, 42)},
  }};
  for (const Poster& p : posters) {
    double da = a - p.azimuth_deg * std::numbers::pi / 180;
    da = std::remainder(da, 2 * std::numbers::pi) * wall;
    if (std::abs(da) < 0.5 * p.width && z > p.bottom && z < p.top) {
      return (std::fmod(z * 7 + da * 3 + 10, 1.0) < 0.5 ? p.color : p.stripe);
    }
  }
  // Plaster, with wallpaper stripes between 60 and 180 degrees.
  Eigen::Vector3f paint = bgr(205, 195, 172);
  const double deg = std::remainder(a, 2 * std::numbers::pi) * 180 / std::numbers::pi;
  if (deg > 60 && deg < 180 && std::fmod(arc + 100, 0.3) < 0.12) paint = bgr(170, 150, 125);
  return paint * mottling(arc, z, footprint);
}

// The room's floor: 0.5 m tiles in two tones with grout, and a striped rug near the centre.
Eigen::Vector3f room_floor_albedo(double x, double y, float footprint) {
  const float m = mottling(x, y, footprint);
  if (x > -1.3 && x < 0.9 && y > -0.8 && y < 1.1) {  // the rug
    const double band = std::fmod(x * 2.5 + 10, 1.0);
    if (band < 0.3) return bgr(125, 25, 40) * m;
    if (band < 0.5) return bgr(185, 158, 112) * m;
    if (band < 0.8) return bgr(45, 65, 115) * m;
    return bgr(230, 228, 222) * m;
  }
  const double u = std::fmod(x + 100, 0.5), v = std::fmod(y + 100, 0.5);
  if (u < 0.012 || v < 0.012) return bgr(70, 68, 66) * m;  // grout
  const bool odd = (static_cast<long>(std::floor(x / 0.5)) + static_cast<long>(std::floor(y / 0.5))) & 1;
  return (odd ? bgr(150, 135, 120) : bgr(190, 180, 165)) * m;
}

// ---------------------------------------------------------------------------------------------

// Shadow rays that ring the light's disc before deciding that a point is fully lit or fully in
// umbra. Eight miss only occluders that clip less than ~2% of the disc between two of them.
constexpr int kRimSamples = 8;  // one Embree packet

enum class Surface : std::uint8_t { kFloor = 0, kWall = 1, kPerformer = 2, kFurniture = 3 };

struct Shaded {
  Eigen::Vector3f color;  // BGR, linear in [0, ~1]
  Surface surface;
  double t;  // ray parameter of the hit (ray direction is unit length)
};

// n points evenly spread over the unit disc (Vogel spiral). The outermost point of each of
// kRimSamples angular sectors goes first, so that the first samples ring the whole disc (see
// StudioRenderer::Impl::visibility()).
std::vector<Eigen::Vector2f> light_disc_samples(int n) {
  std::vector<Eigen::Vector2f> disc;
  const float golden = std::numbers::pi_v<float> * (3.0f - std::sqrt(5.0f));
  for (int k = 0; k < n; ++k) {
    const float r = n == 1 ? 0.0f : std::sqrt((k + 0.5f) / n);
    disc.emplace_back(r * std::cos(k * golden), r * std::sin(k * golden));
  }
  auto sector_of = [](const Eigen::Vector2f& q) {
    const float a = std::atan2(q.y(), q.x()) + std::numbers::pi_v<float>;  // [0, 2 pi]
    return std::min(static_cast<int>(a / (2 * std::numbers::pi_v<float>)*kRimSamples),
                    kRimSamples - 1);
  };
  for (int sector = 0; sector < kRimSamples && sector < n; ++sector) {
    int best = -1;
    for (int k = sector; k < n; ++k) {
      if (sector_of(disc[k]) == sector &&
          (best < 0 || disc[k].squaredNorm() > disc[best].squaredNorm())) {
        best = k;
      }
    }
    if (best >= 0) std::swap(disc[sector], disc[best]);
  }
  return disc;
}

// Slab test: does the ray (o, d) with t in (0, inf) meet the box?
bool ray_hits_box(const Eigen::Vector3f& o, const Eigen::Vector3f& inv_d,
                  const Eigen::AlignedBox3f& box) {
  float t0 = 0, t1 = std::numeric_limits<float>::infinity();
  for (int a = 0; a < 3; ++a) {
    float near = (box.min()[a] - o[a]) * inv_d[a];
    float far = (box.max()[a] - o[a]) * inv_d[a];
    if (near > far) std::swap(near, far);
    // NaN (0 * inf) means the ray runs inside the slab plane: keep the interval.
    if (near > t0) t0 = near;
    if (far < t1) t1 = far;
  }
  return t0 <= t1;
}

}  // namespace

struct StudioRenderer::Impl {
  StudioOptions options;
  ScreenPaint paint;                 // chroma studios
  std::vector<Furniture> furniture;  // the room
  RTCDevice device = nullptr;
  RTCScene scene = nullptr;

  // The performer (empty until set_performer).
  std::vector<Vec3f> normals;                   // #V unit vertex normals
  std::vector<Tri> triangles;                   // #F
  std::vector<std::array<Vec2f, 3>> corner_uv;  // #F, per corner
  std::vector<float> log2_texels_per_metre;     // #F, texture density for mip selection
  std::vector<cv::Mat> mips;                    // CV_32FC3 BGR in [0,1], level 0 = full size
  Eigen::AlignedBox3f bounds;                   // performer bounds, for cheap shadow rejection

  // Key light: unit direction towards its centre, and towards sample points on its disc.
  Eigen::Vector3f light;
  std::vector<Eigen::Vector3f> light_dirs;      // shadow_samples unit directions to the light
  std::vector<Eigen::Vector3f> light_inv_dirs;  // their component-wise inverses (box tests)

  ~Impl() {
    if (scene) rtcReleaseScene(scene);
    if (device) rtcReleaseDevice(device);
  }

  bool has_performer() const { return scene != nullptr; }

  Eigen::Vector3f sample_texture(const Eigen::Vector2f& uv, float level) const;
  float visibility(const Eigen::Vector3f& origin, RenderStats* stats) const;
  Shaded shade(const Eigen::Vector3d& o, const Eigen::Vector3d& d, float pixel_angle,
               RenderStats* stats) const;
  std::optional<Shaded> shade_performer(const Eigen::Vector3d& o, const Eigen::Vector3d& d,
                                        float pixel_angle, RenderStats* stats) const;
  Shaded shade_studio(const Eigen::Vector3d& o, const Eigen::Vector3d& d, float pixel_angle,
                      RenderStats* stats) const;
  Eigen::Vector3f lit(const Eigen::Vector3f& albedo, const Eigen::Vector3d& p,
                      const Eigen::Vector3d& n, RenderStats* stats) const;
};

namespace {

// Bilinear lookup in a CV_32FC3 image at pixel coordinates (x, y) (pixel centres at integers),
// clamped at the borders.
Eigen::Vector3f bilinear(const cv::Mat& image, float x, float y) {
  x = std::clamp(x, 0.0f, static_cast<float>(image.cols - 1));
  y = std::clamp(y, 0.0f, static_cast<float>(image.rows - 1));
  const int x0 = static_cast<int>(x), y0 = static_cast<int>(y);
  const int x1 = std::min(x0 + 1, image.cols - 1), y1 = std::min(y0 + 1, image.rows - 1);
  const float tx = x - x0, ty = y - y0;
  auto at = [&](int r, int c) {
    const cv::Vec3f& p = image.at<cv::Vec3f>(r, c);
    return Eigen::Vector3f(p[0], p[1], p[2]);
  };
  return (at(y0, x0) * (1 - tx) + at(y0, x1) * tx) * (1 - ty) +
         (at(y1, x0) * (1 - tx) + at(y1, x1) * tx) * ty;
}

}  // namespace

// Trilinear (mip-mapped) lookup; `level` 0 is the full-resolution texture.
Eigen::Vector3f StudioRenderer::Impl::sample_texture(const Eigen::Vector2f& uv, float level) const {
  level = std::clamp(level, 0.0f, static_cast<float>(mips.size() - 1));
  const int l0 = static_cast<int>(level);
  const int l1 = std::min(l0 + 1, static_cast<int>(mips.size()) - 1);
  const float f = level - l0;
  auto lookup = [&](int l) {
    const cv::Mat& m = mips[l];
    return bilinear(m, uv.x() * m.cols - 0.5f, (1.0f - uv.y()) * m.rows - 0.5f);
  };
  Eigen::Vector3f c = lookup(l0);
  if (f > 0 && l1 != l0) c = c * (1 - f) + lookup(l1) * f;
  return c;
}

// Fraction of the key light's disc visible from `origin`. The same fixed points on the disc for
// every shaded point make the shadow a function of the 3D point alone, so all cameras see the
// same penumbra (no per-pixel speckle for stereo to mismatch). The first kRimSamples lie on the
// rim of the disc and decide whether the point is clearly lit or clearly in umbra; only
// penumbra points pay for every sample.
float StudioRenderer::Impl::visibility(const Eigen::Vector3f& origin, RenderStats* stats) const {
  if (!has_performer()) return 1.0f;
  const int n = static_cast<int>(light_dirs.size());
  // Visible samples among [begin, end): rays that miss the performer's box are visible without
  // asking Embree; the others go as one packet of up to 8 rays from the same origin.
  auto count_visible = [&](int begin, int end) {
    RTCRay8 packet;
    alignas(32) int valid[8];
    int visible = 0, traced = 0;
    for (int j = 0; j < 8; ++j) {
      const int k = begin + j;
      valid[j] = 0;
      if (k >= end) continue;
      if (!ray_hits_box(origin, light_inv_dirs[k], bounds)) {
        ++visible;
        continue;
      }
      valid[j] = -1;
      ++traced;
      packet.org_x[j] = origin.x();
      packet.org_y[j] = origin.y();
      packet.org_z[j] = origin.z();
      packet.dir_x[j] = light_dirs[k].x();
      packet.dir_y[j] = light_dirs[k].y();
      packet.dir_z[j] = light_dirs[k].z();
      packet.tnear[j] = 1e-3f;  // clears smooth-normal terminator self-hits on a coarse mesh
      packet.tfar[j] = std::numeric_limits<float>::infinity();
      packet.time[j] = 0;
      packet.mask[j] = 0xffffffffu;
      packet.id[j] = static_cast<unsigned>(j);
      packet.flags[j] = 0;
    }
    if (traced == 0) return visible;
    stats->shadow_rays += traced;
    RTCIntersectContext context;
    rtcInitIntersectContext(&context);
    rtcOccluded8(valid, scene, &context, &packet);
    for (int j = 0; j < 8; ++j) {
      if (valid[j] && packet.tfar[j] >= 0) ++visible;  // Embree sets tfar to -inf if occluded
    }
    return visible;
  };
  const int first = std::min(n, kRimSamples);
  int visible = count_visible(0, first);
  if (first < n && (visible == 0 || visible == first)) return visible == 0 ? 0.0f : 1.0f;
  for (int k = first; k < n; k += 8) visible += count_visible(k, std::min(n, k + 8));
  return static_cast<float>(visible) / n;
}

namespace {

// Where the ray (o, d) meets the studio's wall, a vertical cylinder of radius `radius`
// (unbounded upwards so every ray ends on it); infinity when it does not.
double wall_hit(const Eigen::Vector3d& o, const Eigen::Vector3d& d, double radius) {
  double t_wall = std::numeric_limits<double>::infinity();
  const double a = d.x() * d.x() + d.y() * d.y();
  if (a > 1e-12) {
    const double b = o.x() * d.x() + o.y() * d.y();
    const double c = o.x() * o.x() + o.y() * o.y() - radius * radius;
    const double disc = b * b - a * c;
    // The far root: from inside the cylinder it is the only one ahead; from outside it is the
    // back wall, as for a camera placed behind an open screen.
    if (disc >= 0) t_wall = (-b + std::sqrt(disc)) / a;
    if (t_wall <= 0) t_wall = std::numeric_limits<double>::infinity();
  }
  return t_wall;
}

// Where the ray (o, d) meets the floor z = 0 inside the wall; infinity when it does not.
double floor_hit(const Eigen::Vector3d& o, const Eigen::Vector3d& d, double radius) {
  double t_floor = std::numeric_limits<double>::infinity();
  if (d.z() < 0 && o.z() > 0) {
    t_floor = -o.z() / d.z();
    const Eigen::Vector3d p = o + t_floor * d;
    if (p.x() * p.x() + p.y() * p.y() > radius * radius)
      t_floor = std::numeric_limits<double>::infinity();
  }
  return t_floor;
}

}  // namespace

// Colour seen along the ray (o, d), |d| = 1. `pixel_angle` is the angular size of one sample's
// footprint [rad], for texture filtering.
Shaded StudioRenderer::Impl::shade(const Eigen::Vector3d& o, const Eigen::Vector3d& d,
                                   float pixel_angle, RenderStats* stats) const {
  ++stats->camera_rays;
  if (has_performer()) {
    if (const std::optional<Shaded> hit = shade_performer(o, d, pixel_angle, stats)) return *hit;
  }
  return shade_studio(o, d, pixel_angle, stats);
}

// The performer's colour where the ray hits it (textured, lit by the key light with its
// shadows and the ambient light); nullopt where it misses.
std::optional<Shaded> StudioRenderer::Impl::shade_performer(const Eigen::Vector3d& o,
                                                            const Eigen::Vector3d& d,
                                                            float pixel_angle,
                                                            RenderStats* stats) const {
  const float ambient = static_cast<float>(options.ambient);
  const float key = 1.0f - ambient;
  RTCIntersectContext context;
  rtcInitIntersectContext(&context);
  RTCRayHit rh;
  rh.ray.org_x = static_cast<float>(o.x());
  rh.ray.org_y = static_cast<float>(o.y());
  rh.ray.org_z = static_cast<float>(o.z());
  rh.ray.dir_x = static_cast<float>(d.x());
  rh.ray.dir_y = static_cast<float>(d.y());
  rh.ray.dir_z = static_cast<float>(d.z());
  rh.ray.tnear = 0;
  rh.ray.tfar = std::numeric_limits<float>::infinity();
  rh.ray.time = 0;
  rh.ray.mask = 0xffffffffu;
  rh.ray.id = 0;
  rh.ray.flags = 0;
  rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
  rh.hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
  rtcIntersect1(scene, &context, &rh);
  if (rh.hit.geomID == RTC_INVALID_GEOMETRY_ID) return std::nullopt;
  const Tri& tri = triangles[rh.hit.primID];
  const float u = rh.hit.u, v = rh.hit.v, w = 1 - u - v;
  const Eigen::Vector3f df = d.cast<float>();
  Eigen::Vector3f ng(rh.hit.Ng_x, rh.hit.Ng_y, rh.hit.Ng_z);
  ng.normalize();
  Eigen::Vector3f n = (w * normals[tri[0]] + u * normals[tri[1]] + v * normals[tri[2]]);
  n = n.squaredNorm() > 0 ? n.normalized() : ng;
  if (ng.dot(df) > 0) {  // seen from inside (open mesh or back face): shade the side we see
    ng = -ng;
    n = -n;
  }
  const auto& uvs = corner_uv[rh.hit.primID];
  const Eigen::Vector2f uv = w * uvs[0] + u * uvs[1] + v * uvs[2];
  // Footprint of the sample on the surface, in metres, then in texels -> mip level.
  const float cos_incidence = std::max(std::abs(ng.dot(df)), 0.25f);
  const float footprint = rh.ray.tfar * pixel_angle / cos_incidence;
  // The -0.5 bias keeps texture detail: the isotropic footprint over-blurs otherwise.
  const float level =
      std::log2(std::max(footprint, 1e-9f)) + log2_texels_per_metre[rh.hit.primID] - 0.5f;
  const Eigen::Vector3f albedo = sample_texture(uv, level);

  const Eigen::Vector3f p = (o + rh.ray.tfar * d).cast<float>();
  const float n_dot_l = n.dot(light);
  float direct = 0;
  if (n_dot_l > 0 && ng.dot(light) > -0.2f) {
    direct = n_dot_l * visibility(p + 1e-4f * ng, stats);
  }
  // Ambient a little stronger from above (sky/ceiling bounce) so shapes read in shadow.
  const float fill = ambient * (0.85f + 0.15f * n.z());
  return Shaded{albedo * (fill + key * direct), Surface::kPerformer, rh.ray.tfar};
}

// `albedo` at p (normal n) lit by the key light (with the performer's shadow) and the ambient
// light.
Eigen::Vector3f StudioRenderer::Impl::lit(const Eigen::Vector3f& albedo, const Eigen::Vector3d& p,
                                          const Eigen::Vector3d& n, RenderStats* stats) const {
  const float ambient = static_cast<float>(options.ambient);
  const float key = 1.0f - ambient;
  const float n_dot_l = n.cast<float>().dot(light);
  float direct = 0;
  if (n_dot_l > 0) direct = n_dot_l * visibility((p + 1e-4 * n).cast<float>(), stats);
  return Eigen::Vector3f(albedo * (ambient + key * direct));
}

// The studio: floor z = 0 inside a vertical cylinder of radius wall_distance (the screen or
// the room's wall, unbounded upwards so every ray ends on it), and the room's furniture.
Shaded StudioRenderer::Impl::shade_studio(const Eigen::Vector3d& o, const Eigen::Vector3d& d,
                                          float pixel_angle, RenderStats* stats) const {
  const float ambient = static_cast<float>(options.ambient);
  const float key = 1.0f - ambient;
  const double radius = options.wall_distance;
  const bool room = options.room();
  const double t_wall = wall_hit(o, d, radius);
  const double t_floor = floor_hit(o, d, radius);
  double t_box = std::numeric_limits<double>::infinity();
  const Furniture* piece = nullptr;
  Eigen::Vector3d box_normal = Eigen::Vector3d::Zero();
  for (const Furniture& f : furniture) {
    double t;
    Eigen::Vector3d n;
    if (hit_furniture(f, o, d, &t, &n) && t < t_box) {
      t_box = t;
      piece = &f;
      box_normal = n;
    }
  }
  if (piece && t_box < t_floor && t_box < t_wall) {
    const Eigen::Vector3d p = o + t_box * d;
    const float footprint = static_cast<float>(t_box * pixel_angle);
    return {lit(furniture_albedo(*piece, p, footprint), p, box_normal, stats), Surface::kFurniture,
            t_box};
  }
  if (t_floor < t_wall) {
    const Eigen::Vector3d p = o + t_floor * d;
    const float footprint = static_cast<float>(t_floor * pixel_angle / std::max(-d.z(), 0.05));
    if (room) {
      return {lit(room_floor_albedo(p.x(), p.y(), footprint), p, Eigen::Vector3d::UnitZ(), stats),
              Surface::kFloor, t_floor};
    }
    const Eigen::Vector3f albedo = floor_albedo(paint.floor, p.x(), p.y(), footprint);
    const float n_dot_l = light.z();
    float direct = 0;
    if (n_dot_l > 0) {
      direct = n_dot_l * visibility(Eigen::Vector3f(p.x(), p.y(), 1e-4f), stats);
    }
    return {albedo * (ambient + key * direct), Surface::kFloor, t_floor};
  }
  if (std::isfinite(t_wall)) {
    const Eigen::Vector3d p = o + t_wall * d;
    if (room) {
      const float footprint = static_cast<float>(t_wall * pixel_angle);
      const Eigen::Vector3d inward = -Eigen::Vector3d(p.x(), p.y(), 0).normalized();
      return {lit(room_wall_albedo(std::atan2(p.y(), p.x()), p.z(), radius, footprint), p, inward,
                  stats),
              Surface::kWall, t_wall};
    }
    return {backdrop_color(paint.wall, std::atan2(p.y(), p.x()), p.z(), options.backdrop_variation),
            Surface::kWall, t_wall};
  }
  // Only a camera outside the studio looking away from it gets here: show the screen colour.
  return {backdrop_color(paint.wall, std::atan2(d.y(), d.x()), o.z(), options.backdrop_variation),
          Surface::kWall, std::numeric_limits<double>::infinity()};
}

void StudioOptions::check() const {
  if (backdrop == "green" || backdrop == "blue" || backdrop == "room") return;
  const bool hex = backdrop.size() == 7 && backdrop[0] == '#' &&
                   std::all_of(backdrop.begin() + 1, backdrop.end(),
                               [](char ch) { return std::isxdigit(static_cast<unsigned char>(ch)); });
  if (!hex) {
    throw ConfigError(fmt::format(
        "backdrop '{}': expected green, blue, room or a colour #RRGGBB", backdrop));
  }
}

StudioRenderer::StudioRenderer(const StudioOptions& options) : impl_(std::make_unique<Impl>()) {
  Impl& s = *impl_;
  options.check();
  s.options = options;
  if (options.room()) {
    s.paint = screen_paint("green");  // only seen by a camera outside the room looking away
    s.furniture = room_furniture(static_cast<float>(options.wall_distance));
  } else {
    s.paint = screen_paint(options.backdrop);
  }
  const double deg = std::numbers::pi / 180.0;
  const double el = options.light_elevation * deg, az = options.light_azimuth * deg;
  s.light = Eigen::Vector3d(std::cos(el) * std::cos(az), std::cos(el) * std::sin(az), std::sin(el))
                .cast<float>()
                .normalized();
  // Directions to points spread over the light's disc (an area light: soft shadows).
  const Eigen::Vector3f helper =
      std::abs(s.light.z()) < 0.9f ? Eigen::Vector3f::UnitZ() : Eigen::Vector3f::UnitX();
  const Eigen::Vector3f u = s.light.cross(helper).normalized(), v = s.light.cross(u);
  const float tan_radius = static_cast<float>(std::tan(options.light_radius * deg));
  for (const Eigen::Vector2f& q : light_disc_samples(std::max(1, options.shadow_samples))) {
    s.light_dirs.push_back((s.light + tan_radius * (q.x() * u + q.y() * v)).normalized());
    s.light_inv_dirs.push_back(s.light_dirs.back().cwiseInverse());
  }
  s.device = rtcNewDevice(nullptr);
  if (!s.device) throw Error("renderer: cannot create the Embree device");
}

StudioRenderer::~StudioRenderer() = default;

void StudioRenderer::set_performer(const Mesh& mesh, const cv::Mat& texture) {
  Impl& s = *impl_;
  mesh.check("performer mesh");
  if (mesh.empty()) throw InputError("performer mesh: no vertices or no triangles");
  const bool per_corner = !mesh.uv_triangles.empty();
  if (!per_corner && mesh.uvs.size() != mesh.num_vertices()) {
    throw InputError(
        fmt::format("performer mesh: needs texture coordinates ({} UVs for {} vertices)",
                    mesh.uvs.size(), mesh.num_vertices()));
  }
  if (texture.empty() || texture.type() != CV_8UC3) {
    throw InputError("performer texture: expected a non-empty 8-bit 3-channel (BGR) image");
  }

  // Smooth-shading normals: the mesh's own, or area-weighted ones.
  if (mesh.normals.size() == mesh.num_vertices()) {
    s.normals = mesh.normals;
  } else {
    Mesh with_normals;
    with_normals.positions = mesh.positions;
    with_normals.triangles = mesh.triangles;
    compute_vertex_normals(with_normals);
    s.normals = std::move(with_normals.normals);
  }
  s.triangles = mesh.triangles;

  // Per-corner UVs and each triangle's texture density (texels per metre), which turns a
  // sample's footprint into a mip level.
  const std::size_t nf = mesh.num_triangles();
  s.corner_uv.resize(nf);
  s.log2_texels_per_metre.resize(nf);
  const double texels = static_cast<double>(texture.cols) * texture.rows;
  for (std::size_t f = 0; f < nf; ++f) {
    const Tri& uv_tri = per_corner ? mesh.uv_triangles[f] : mesh.triangles[f];
    for (int c = 0; c < 3; ++c) s.corner_uv[f][c] = mesh.uvs[uv_tri[c]];
    const Tri& tri = mesh.triangles[f];
    const Vec3f e1 = mesh.positions[tri[1]] - mesh.positions[tri[0]];
    const Vec3f e2 = mesh.positions[tri[2]] - mesh.positions[tri[0]];
    const double world_area = 0.5 * e1.cross(e2).norm();
    const Vec2f t1 = s.corner_uv[f][1] - s.corner_uv[f][0];
    const Vec2f t2 = s.corner_uv[f][2] - s.corner_uv[f][0];
    const double uv_area = 0.5 * std::abs(t1.x() * t2.y() - t1.y() * t2.x()) * texels;
    s.log2_texels_per_metre[f] =
        static_cast<float>(0.5 * std::log2(std::max(uv_area, 1e-12) / std::max(world_area, 1e-18)));
  }

  // Mip pyramid (Gaussian-filtered halvings) in float for cheap bilinear lookups.
  s.mips.clear();
  cv::Mat level;
  texture.convertTo(level, CV_32FC3, 1.0 / 255.0);
  s.mips.push_back(level);
  while (std::min(level.cols, level.rows) >= 4) {
    cv::Mat next;
    cv::pyrDown(level, next);
    s.mips.push_back(next);
    level = next;
  }

  s.bounds.setEmpty();
  for (const Vec3f& p : mesh.positions) s.bounds.extend(p);

  // The Embree scene: one triangle mesh, rebuilt per frame (the posed mesh moves).
  if (s.scene) rtcReleaseScene(s.scene);
  s.scene = nullptr;
  RTCScene scene = rtcNewScene(s.device);
  RTCGeometry geometry = rtcNewGeometry(s.device, RTC_GEOMETRY_TYPE_TRIANGLE);
  auto* vertices = static_cast<float*>(rtcSetNewGeometryBuffer(geometry, RTC_BUFFER_TYPE_VERTEX, 0,
                                                               RTC_FORMAT_FLOAT3, 3 * sizeof(float),
                                                               mesh.num_vertices()));
  auto* indices = static_cast<unsigned*>(rtcSetNewGeometryBuffer(
      geometry, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3, 3 * sizeof(unsigned), nf));
  if (!vertices || !indices) {
    rtcReleaseGeometry(geometry);
    rtcReleaseScene(scene);
    throw Error("renderer: Embree could not allocate the performer buffers");
  }
  for (std::size_t i = 0; i < mesh.num_vertices(); ++i) {
    for (int c = 0; c < 3; ++c) vertices[3 * i + c] = mesh.positions[i][c];
  }
  for (std::size_t f = 0; f < nf; ++f) {
    for (int c = 0; c < 3; ++c) indices[3 * f + c] = static_cast<unsigned>(mesh.triangles[f][c]);
  }
  rtcCommitGeometry(geometry);
  rtcAttachGeometry(scene, geometry);
  rtcReleaseGeometry(geometry);
  rtcCommitScene(scene);
  if (rtcGetDeviceError(s.device) != RTC_ERROR_NONE) {
    rtcReleaseScene(scene);
    throw Error("renderer: Embree failed to build the performer BVH");
  }
  s.scene = scene;
}

namespace {

// Adds a row chunk's counts to the view's totals (integer sums: independent of scheduling).
class StatsSink {
 public:
  void add(const RenderStats& s) {
    camera_rays_ += s.camera_rays;
    shadow_rays_ += s.shadow_rays;
    supersampled_pixels_ += s.supersampled_pixels;
  }
  RenderStats total() const {
    return {camera_rays_.load(), shadow_rays_.load(), supersampled_pixels_.load()};
  }

 private:
  std::atomic<std::int64_t> camera_rays_{0}, shadow_rays_{0}, supersampled_pixels_{0};
};

// True when the 1-spp pass shows an edge in the pixel's 3x3 neighbourhood: another surface
// (performer outline, floor/screen line) or, on the performer, a depth step of more than 3 %
// (an arm in front of the body).
bool on_edge(const cv::Mat& surface, const cv::Mat& depth, int x, int y) {
  const std::uint8_t own = surface.at<std::uint8_t>(y, x);
  const float own_depth = depth.at<float>(y, x);
  for (int yy = std::max(0, y - 1); yy <= std::min(surface.rows - 1, y + 1); ++yy) {
    const auto* row = surface.ptr<std::uint8_t>(yy);
    const auto* depth_row = depth.ptr<float>(yy);
    for (int xx = std::max(0, x - 1); xx <= std::min(surface.cols - 1, x + 1); ++xx) {
      if (row[xx] != own) return true;
      if (std::abs(depth_row[xx] - own_depth) > 0.03f * own_depth) return true;
    }
  }
  return false;
}

// Zero-mean Gaussian sensor noise for the three channels of one pixel: Box-Muller pairs from
// a hash of (seed, pixel), so the noise is a pure function of both.
std::array<float, 3> sensor_noise(std::uint64_t seed, std::uint64_t pixel, float sigma) {
  std::array<float, 4> n{};
  for (int pair = 0; pair < 2; ++pair) {
    const std::uint64_t bits = hash3(seed, pixel, static_cast<std::uint64_t>(pair));
    const float u1 = (static_cast<float>(bits >> 40) + 0.5f) * (1.0f / 16777216.0f);
    const float u2 = static_cast<float>((bits >> 8) & 0xffffffu) * (1.0f / 16777216.0f);
    const float r = sigma * std::sqrt(-2.0f * std::log(u1));
    n[2 * pair] = r * std::cos(2 * std::numbers::pi_v<float> * u2);
    n[2 * pair + 1] = r * std::sin(2 * std::numbers::pi_v<float> * u2);
  }
  return {n[0], n[1], n[2]};
}

std::uint64_t pixel_key(int x, int y) {
  return (static_cast<std::uint64_t>(static_cast<std::uint32_t>(y)) << 32) |
         static_cast<std::uint32_t>(x);
}

}  // namespace

RenderedView StudioRenderer::render(const Camera& camera, std::uint64_t noise_seed,
                                    float gain) const {
  const Impl& s = *impl_;
  const Intrinsics& k = camera.intrinsics;
  if (k.width <= 0 || k.height <= 0 || !(k.fx > 0) || !(k.fy > 0)) {
    throw InputError(fmt::format("camera {}: bad intrinsics ({}x{}, f {} {})", camera.name, k.width,
                                 k.height, k.fx, k.fy));
  }
  const int width = k.width, height = k.height;
  // Angular size of a pixel, for texture and floor-pattern filtering.
  const float pixel_angle = static_cast<float>(1.0 / std::sqrt(k.fx * k.fy));
  const Eigen::Vector3d z_axis = camera.camera_from_world.linear().row(2).transpose();
  const Eigen::Vector3d centre = camera.center();

  RenderedView view;
  view.silhouette = cv::Mat::zeros(height, width, CV_8UC1);
  view.depth = cv::Mat::zeros(height, width, CV_32FC1);
  view.image.create(height, width, CV_8UC3);
  cv::Mat color(height, width, CV_32FC3);
  cv::Mat surface(height, width, CV_8UC1);
  StatsSink stats;

  // Pass 1: one ray through each pixel centre gives the silhouette, the depth and the colour.
  tbb::parallel_for(tbb::blocked_range<int>(0, height), [&](const tbb::blocked_range<int>& rows) {
    RenderStats local;
    for (int y = rows.begin(); y < rows.end(); ++y) {
      auto* col = color.ptr<cv::Vec3f>(y);
      auto* surf = surface.ptr<std::uint8_t>(y);
      auto* sil = view.silhouette.ptr<std::uint8_t>(y);
      auto* dep = view.depth.ptr<float>(y);
      for (int x = 0; x < width; ++x) {
        const Ray ray = camera.unproject(Eigen::Vector2d(x + 0.5, y + 0.5));
        const Shaded h = s.shade(ray.origin, ray.direction, pixel_angle, &local);
        col[x] = cv::Vec3f(h.color.x(), h.color.y(), h.color.z());
        surf[x] = static_cast<std::uint8_t>(h.surface);
        if (h.surface == Surface::kPerformer) {
          sil[x] = 255;
          dep[x] = static_cast<float>((ray.origin + h.t * ray.direction - centre).dot(z_axis));
        }
      }
    }
    stats.add(local);
  });

  // Pass 2: anti-aliasing where the 3x3 neighbourhood crosses an edge (see on_edge()), then
  // sensor noise and quantisation.
  const int spp = std::max(1, s.options.samples_per_pixel);
  const float sub_angle = pixel_angle / std::sqrt(static_cast<float>(spp));
  const float sigma = static_cast<float>(s.options.noise_sigma);
  tbb::parallel_for(tbb::blocked_range<int>(0, height), [&](const tbb::blocked_range<int>& rows) {
    RenderStats local;
    for (int y = rows.begin(); y < rows.end(); ++y) {
      const auto* col = color.ptr<cv::Vec3f>(y);
      auto* out = view.image.ptr<cv::Vec3b>(y);
      for (int x = 0; x < width; ++x) {
        Eigen::Vector3f c(col[x][0], col[x][1], col[x][2]);
        const std::uint64_t key = pixel_key(x, y);
        if (spp > 1 && on_edge(surface, view.depth, x, y)) {
          // Stratified jitter: Hammersley points shifted per pixel (Cranley-Patterson rotation).
          const std::uint64_t h = hash3(0x5eedull, key, 0);
          const double jx = to_unit(h), jy = to_unit(mix64(h));
          Eigen::Vector3f sum = Eigen::Vector3f::Zero();
          for (int i = 0; i < spp; ++i) {
            double sx = (i + 0.5) / spp + jx, sy = radical_inverse2(i) + jy;
            sx -= std::floor(sx);
            sy -= std::floor(sy);
            const Ray ray = camera.unproject(Eigen::Vector2d(x + sx, y + sy));
            sum += s.shade(ray.origin, ray.direction, sub_angle, &local).color;
          }
          c = sum / static_cast<float>(spp);
          ++local.supersampled_pixels;
        }
        if (gain != 1.0f) c *= gain;
        std::array<float, 3> noise{};
        if (sigma > 0) noise = sensor_noise(noise_seed, key, sigma);
        for (int ch = 0; ch < 3; ++ch) {
          const long v = std::lround(c[ch] * 255.0f + noise[ch]);
          out[x][ch] = static_cast<std::uint8_t>(std::clamp(v, 0l, 255l));
        }
      }
    }
    stats.add(local);
  });
  view.stats = stats.total();
  return view;
}

}  // namespace fourd::synth
