// Segmentation on small synthetic images: the learned chroma key of screens of any colour, plate
// difference under a gain change and a shadow, supplied masks, the method auto picks, and the
// cross-camera consistency warning of the stage.
#include "stages/segment/segment.h"

#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <opencv2/imgproc.hpp>
#include <random>

#include "pipeline/core/colmap_model.h"
#include "pipeline/core/error.h"
#include "pipeline/core/files.h"
#include "pipeline/core/image_io.h"
#include "pipeline/core/session.h"
#include "stages/segment/consistency.h"
#include "stages/segment/plate.h"
#include "stages/synth/render.h"
#include "stages/validate/validate.h"
#include "tests/scratch_dir.h"

namespace fourd::segment {

namespace {

namespace fs = std::filesystem;

constexpr int kW = 160, kH = 120;

// The performer of the synthetic frames: a rectangle of several clothing colours.
const cv::Rect kPerformer(60, 20, 40, 80);

cv::Mat performer_mask() {
  cv::Mat m = cv::Mat::zeros(kH, kW, CV_8U);
  m(kPerformer).setTo(255);
  return m;
}

void add_noise(cv::Mat& bgr, std::mt19937& rng, double sigma) {
  cv::Mat noise(bgr.size(), CV_32FC3);
  std::normal_distribution<float> n(0.f, static_cast<float>(sigma));
  for (int r = 0; r < noise.rows; ++r) {
    for (int c = 0; c < noise.cols; ++c) noise.at<cv::Vec3f>(r, c) = {n(rng), n(rng), n(rng)};
  }
  cv::Mat f;
  bgr.convertTo(f, CV_32FC3);
  f += noise;
  f.convertTo(bgr, CV_8UC3);
}

// A frame of a chroma screen of colour `rgb` (brighter at the top, a shadow on the floor), with
// the performer in skin, red, grey and yellow.
cv::Mat chroma_frame(const cv::Vec3b& rgb, std::mt19937& rng) {
  cv::Mat bgr(kH, kW, CV_8UC3);
  for (int r = 0; r < kH; ++r) {
    const double shade = (r > 95 && r < 110) ? 0.45 : 1.0 - 0.15 * r / kH;
    bgr.row(r).setTo(cv::Scalar(rgb[2] * shade, rgb[1] * shade, rgb[0] * shade));
  }
  const cv::Rect p = kPerformer;
  bgr(cv::Rect(p.x, p.y, p.width, 15)).setTo(cv::Scalar(145, 180, 225));        // skin
  bgr(cv::Rect(p.x, p.y + 15, p.width, 30)).setTo(cv::Scalar(40, 40, 200));     // red shirt
  bgr(cv::Rect(p.x, p.y + 45, p.width / 2, 35)).setTo(cv::Scalar(90, 95, 110)); // warm grey
  bgr(cv::Rect(p.x + p.width / 2, p.y + 45, p.width / 2, 35)).setTo(cv::Scalar(40, 190, 225));
  add_noise(bgr, rng, 2.0);
  return bgr;
}

double iou(const cv::Mat& a, const cv::Mat& b) { return fourd::validate::silhouette_iou(a, b); }

double hue_distance(double a, double b) { return std::abs(std::remainder(a - b, 360.0)); }

void expect_chroma_studio_keyed(const cv::Vec3b& rgb, double expected_hue) {
  std::mt19937 rng(5);
  std::vector<cv::Mat> frames;
  for (int i = 0; i < 3; ++i) frames.push_back(chroma_frame(rgb, rng));
  const Backdrop b = learn_backdrop(frames, "cam00");
  EXPECT_LT(hue_distance(b.hue_deg, expected_hue), 8.0) << b.hue_deg;
  EXPECT_GT(b.fraction, 0.6);
  EXPECT_NEAR(b.rgb[0], rgb[0] * 0.93, 12);
  std::vector<cv::Mat> maps;
  for (const cv::Mat& f : frames) maps.push_back(keyness(f, b, 16));
  const KeyModel key = learn_key(maps);
  const SegmentOptions options;
  for (const cv::Mat& f : frames) {
    EXPECT_GT(iou(key_silhouette(f, b, key, options), performer_mask()), 0.98);
  }
}

TEST(SegmentChroma, LearnsABlueScreen) { expect_chroma_studio_keyed({25, 70, 185}, 225); }

TEST(SegmentChroma, LearnsAMagentaScreen) { expect_chroma_studio_keyed({200, 40, 190}, 302); }

TEST(SegmentChroma, LearnsAGreenScreen) { expect_chroma_studio_keyed({40, 170, 60}, 128); }

TEST(SegmentChroma, PureGreenIsTheClassicKey) {
  // Along pure green the generalised keyness is (G - max(R, B)) / (G + offset).
  Backdrop green;
  green.direction = chroma_direction(120);
  cv::Mat bgr(1, 5, CV_8UC3);
  const std::vector<cv::Vec3b> colours = {{60, 170, 40}, {40, 40, 200}, {0, 0, 0}, {200, 100, 30},
                                          {255, 255, 255}};
  for (int i = 0; i < 5; ++i) bgr.at<cv::Vec3b>(0, i) = colours[i];
  const cv::Mat k = keyness(bgr, green, 16);
  for (int i = 0; i < 5; ++i) {
    const float b = colours[i][0], g = colours[i][1], r = colours[i][2];
    EXPECT_NEAR(k.at<float>(0, i), (g - std::max(r, b)) / (g + 16), 1e-4) << i;
  }
}

TEST(SegmentChroma, AGreyStudioHasNoBackdropColour) {
  std::mt19937 rng(1);
  std::vector<cv::Mat> frames = {chroma_frame({128, 128, 128}, rng)};
  try {
    learn_backdrop(frames, "cam03");
    FAIL() << "a grey studio was keyed";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("cam03"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("plates"), std::string::npos) << e.what();
  }
}

// A cluttered static background: colour blocks and stripes, some of the performer's colours.
cv::Mat room(std::mt19937& rng) {
  cv::Mat bgr(kH, kW, CV_8UC3, cv::Scalar(150, 170, 190));
  for (int x = 0; x + 5 <= kW; x += 12) bgr(cv::Rect(x, 0, 5, kH / 2)).setTo(cv::Scalar(120, 130, 150));
  bgr(cv::Rect(10, 40, 50, 50)).setTo(cv::Scalar(40, 40, 200));    // red cupboard
  bgr(cv::Rect(110, 30, 40, 60)).setTo(cv::Scalar(115, 65, 45));   // denim-blue shelf
  for (int x = 0; x < kW; x += 20) {                               // tiled floor
    bgr(cv::Rect(x, 90, 10, 30)).setTo(cv::Scalar(100, 120, 140));
  }
  add_noise(bgr, rng, 2.0);
  return bgr;
}

// Three plates of the empty studio: `empty` with fresh noise each.
std::vector<cv::Mat> noisy_plates(const cv::Mat& empty, std::mt19937& rng) {
  std::vector<cv::Mat> plates;
  for (int i = 0; i < 3; ++i) {
    cv::Mat p = empty.clone();
    add_noise(p, rng, 2.0);
    plates.push_back(p);
  }
  return plates;
}

TEST(SegmentPlate, ToleratesAGainChangeAndAShadow) {
  std::mt19937 rng(3);
  cv::Mat empty = room(rng);
  const PlateModel model = learn_plate(noisy_plates(empty, rng), "cam00");
  EXPECT_NEAR(model.sigma, 2.0, 0.4);  // the noise that differs between the plates
  // The frame: 4% more light, the performer's shadow on the floor, the performer.
  cv::Mat frame;
  empty.convertTo(frame, CV_8UC3, 1.04);
  const cv::Rect shadow(100, 95, 50, 20);
  cv::Mat shadowed;
  frame(shadow).convertTo(shadowed, CV_8UC3, 0.42);
  shadowed.copyTo(frame(shadow));
  const cv::Rect p = kPerformer;
  frame(cv::Rect(p.x, p.y, p.width, 40)).setTo(cv::Scalar(60, 60, 180));  // red, near the cupboard's
  frame(cv::Rect(p.x, p.y + 40, p.width, 40)).setTo(cv::Scalar(90, 90, 95));
  add_noise(frame, rng, 2.0);
  const cv::Vec3d gain = background_gain(frame, model);
  for (int ch = 0; ch < 3; ++ch) EXPECT_NEAR(gain[ch], 1.04, 0.01);
  const cv::Mat mask = plate_silhouette(frame, model, SegmentOptions{});
  EXPECT_GT(iou(mask, performer_mask()), 0.97);
  EXPECT_LT(cv::countNonZero(mask(shadow)), shadow.area() / 100) << "the shadow is foreground";
}

// A disc of `colour` over `empty`, each pixel the mix of the two by the fraction of the samples
// `samples(x, y)` gives (offsets within the pixel, row by row) that fall in the disc. `truth`:
// the pixels whose centre it covers; `own`: those whose samples it covers at least half of.
struct Disc {
  cv::Mat frame, truth, own;
};
template <class Samples>
Disc render_disc(const cv::Mat& empty, cv::Point2d centre, double radius, const cv::Vec3f& colour,
                 Samples samples) {
  Disc d{empty.clone(), cv::Mat::zeros(empty.size(), CV_8U), cv::Mat::zeros(empty.size(), CV_8U)};
  auto inside = [&](double px, double py) { return std::hypot(px - centre.x, py - centre.y) < radius; };
  for (int y = 0; y < empty.rows; ++y) {
    for (int x = 0; x < empty.cols; ++x) {
      const std::vector<cv::Point2d> offsets = samples(x, y);
      int covered = 0;
      for (const cv::Point2d& o : offsets) covered += inside(x + o.x, y + o.y);
      const float a = static_cast<float>(covered) / static_cast<float>(offsets.size());
      cv::Vec3b& px = d.frame.at<cv::Vec3b>(y, x);
      for (int ch = 0; ch < 3; ++ch) px[ch] = cv::saturate_cast<std::uint8_t>(a * colour[ch] + (1 - a) * px[ch]);
      d.truth.at<std::uint8_t>(y, x) = inside(x + 0.5, y + 0.5) ? 255 : 0;
      d.own.at<std::uint8_t>(y, x) = a >= 0.5f ? 255 : 0;
    }
  }
  return d;
}

// A denim-blue disc (grey would pass for shadow) over a light wall, 0.35 of the image's height
// in radius, off the pixel grid: the wall's plate learnt from noisy plates, the disc rendered
// with `samples`, then the frame given the plates' noise.
struct DiscOnAWall {
  PlateModel model;
  Disc disc;
  int perimeter;  // [px]
};
template <class Samples>
DiscOnAWall disc_on_a_wall(std::mt19937& rng, Samples samples) {
  const cv::Mat empty(kH, kW, CV_8UC3, cv::Scalar(200, 205, 210));
  DiscOnAWall scene;
  scene.model = learn_plate(noisy_plates(empty, rng), "cam00");
  const double radius = 0.35 * kH;
  scene.disc = render_disc(empty, {kW / 2.0 + 0.3, kH / 2.0 - 0.2}, radius, {140, 70, 40}, samples);
  add_noise(scene.disc.frame, rng, 2.0);
  scene.perimeter = static_cast<int>(2 * M_PI * radius);
  return scene;
}

// The outline of a performer against a contrasting plate: its pixels are partly both, and already
// at a small coverage far more than the noise off the plate. A disc rendered 4x4 supersampled
// (the pixel's colour is its coverage's mix): the silhouette is the pixels whose centre it
// covers, not one pixel wider all round.
TEST(SegmentPlate, MixedOutlinePixelsGoByTheirCoverage) {
  std::mt19937 rng(5);
  const DiscOnAWall scene = disc_on_a_wall(rng, [](int, int) {
    std::vector<cv::Point2d> samples;
    for (int sy = 0; sy < 4; ++sy) {
      for (int sx = 0; sx < 4; ++sx) samples.emplace_back((sx + 0.5) / 4, (sy + 0.5) / 4);
    }
    return samples;
  });
  const cv::Mat& truth = scene.disc.truth;
  const cv::Mat mask = plate_silhouette(scene.disc.frame, scene.model, SegmentOptions{});
  const int perimeter = scene.perimeter;
  EXPECT_LT(cv::countNonZero(mask & ~truth), perimeter / 4) << "a ring of mixed pixels taken whole";
  EXPECT_LT(cv::countNonZero(truth & ~mask), perimeter / 4) << "the outline eaten into";
}

// The outline of a disc rendered as the synthetic studio renders it: an outline pixel is the mean
// of 4 jittered samples, so its own coverage is a coarse, noisy guess at whether the disc covers
// its centre (the silhouette's truth). refine_plate_outline judges the outline by the coverage
// smoothed over the neighbours: from a mask a pixel too wide all round, it gets nearer the truth
// than each pixel's own exact coverage at one half does.
TEST(SegmentPlate, TheOutlineGoesByItsNeighboursCoverageToo) {
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> jitter(0.0, 1.0);
  const DiscOnAWall scene = disc_on_a_wall(rng, [&](int, int) {
    const double jx = jitter(rng), jy = jitter(rng);
    std::vector<cv::Point2d> samples;
    for (int i = 0; i < 4; ++i) {  // stratified in x and y, shifted per pixel
      samples.emplace_back(std::fmod((i + 0.5) / 4 + jx, 1.0),
                           std::fmod(std::array<double, 4>{0, 0.5, 0.25, 0.75}[i] + jy, 1.0));
    }
    return samples;
  });
  // own: each pixel by its own coverage
  const cv::Mat &truth = scene.disc.truth, &own = scene.disc.own;
  cv::Mat mask;
  cv::dilate(truth, mask, cv::Mat());
  refine_plate_outline(mask, scene.disc.frame, scene.model);
  const int wrong = cv::countNonZero(mask ^ truth), wrong_own = cv::countNonZero(own ^ truth);
  const int perimeter = scene.perimeter;
  EXPECT_GT(wrong_own, perimeter / 10) << "4 samples a pixel should leave the outline noisy";
  EXPECT_LT(wrong, wrong_own * 3 / 4) << "no better than each pixel's own coverage";
  EXPECT_LT(cv::countNonZero(mask & ~truth), perimeter / 8) << "the ring of mixed pixels kept";
  EXPECT_LT(cv::countNonZero(truth & ~mask), perimeter / 8) << "the outline eaten into";
}

// With one sample a pixel the edges are sharp: every outline pixel is all performer or all
// plate, and smoothing their coverage would only round the corners off and thin the limbs. A
// block and a limb 3 px wide keep every pixel, corners and fingertip included.
TEST(SegmentPlate, SharpEdgesKeepTheirCorners) {
  std::mt19937 rng(17);
  cv::Mat empty(kH, kW, CV_8UC3, cv::Scalar(200, 205, 210));  // a light wall
  const PlateModel model = learn_plate(noisy_plates(empty, rng), "cam00");
  cv::Mat frame = empty.clone(), truth = cv::Mat::zeros(kH, kW, CV_8U);
  const cv::Rect block(50, 30, 40, 50), limb(90, 50, 30, 3);
  for (const cv::Rect& r : {block, limb}) {
    frame(r).setTo(cv::Scalar(140, 70, 40));
    truth(r).setTo(255);
  }
  add_noise(frame, rng, 2.0);
  cv::Mat mask = truth.clone();
  refine_plate_outline(mask, frame, model);
  EXPECT_EQ(cv::countNonZero(mask ^ truth), 0);
  EXPECT_EQ(mask.at<std::uint8_t>(block.y, block.x), 255) << "a corner rounded off";
  EXPECT_EQ(mask.at<std::uint8_t>(limb.y + 1, limb.x + limb.width - 1), 255) << "the limb's tip";
}

// The performer's shadow beside its shoe on a striped rug: the window that tells a shadow (the
// rug's stripes show through) from the performer (they do not) holds the shoe too, which hides
// the stripes. The shadow's pixels next to the shoe are background all the same.
TEST(SegmentPlate, AShadowBesideTheShoeShowsTheRugThroughIt) {
  std::mt19937 rng(13);
  cv::Mat empty(kH, kW, CV_8UC3);
  for (int y = 0; y < kH; ++y) {  // stripes of red and beige, 3 px each
    empty.row(y).setTo((y / 3) % 2 ? cv::Scalar(60, 50, 170) : cv::Scalar(150, 180, 210));
  }
  PlateModel model = learn_plate(noisy_plates(empty, rng), "cam00");
  model.shadow_region = cv::Mat(kH, kW, CV_8U, cv::Scalar(255));  // all of it floor
  cv::Mat frame = empty.clone();
  const cv::Rect shadow(40, 50, 80, 30), shoe(60, 40, 40, 20);  // the shoe's sole in the shadow
  cv::Mat darker;
  frame(shadow).convertTo(darker, CV_8UC3, 0.5);
  darker.copyTo(frame(shadow));
  frame(shoe).setTo(cv::Scalar(40, 200, 230));  // a yellow shoe, brighter than the shadow
  add_noise(frame, rng, 2.0);
  const cv::Mat mask = plate_silhouette(frame, model, SegmentOptions{});
  const cv::Mat shoe_mask = cv::Mat::zeros(kH, kW, CV_8U);
  shoe_mask(shoe).setTo(255);
  EXPECT_GT(cv::countNonZero(mask(shoe)), shoe.area() * 95 / 100);
  cv::Mat beside;  // the shadow within 3 px of the shoe
  cv::dilate(shoe_mask, beside, cv::Mat(), {-1, -1}, 3);
  beside &= ~shoe_mask;
  cv::Mat in_shadow = cv::Mat::zeros(kH, kW, CV_8U);
  in_shadow(shadow).setTo(255);
  beside &= in_shadow;
  EXPECT_LT(cv::countNonZero(mask & beside), cv::countNonZero(beside) / 10)
      << "the shadow beside the shoe taken for the performer";
}

// Shadows are background only where the plate shows the floor near the rig's centre: a dark
// grey coat over a grey wall, darker than the wall by a shadow's factor, is the performer.
TEST(SegmentPlate, ShadowsOnlyWhereTheFloorCanTakeThem) {
  std::mt19937 rng(5);
  cv::Mat empty = room(rng);
  const PlateModel anywhere = learn_plate({empty}, "cam00");
  PlateModel floor_only = anywhere;
  floor_only.shadow_region = cv::Mat::zeros(kH, kW, CV_8U);
  floor_only.shadow_region(cv::Rect(0, 90, kW, kH - 90)).setTo(255);  // the tiled floor
  cv::Mat frame = empty.clone();
  const cv::Rect shadow(100, 95, 50, 20), coat(60, 10, 30, 60);  // coat over the wall
  cv::Mat darker;
  frame(shadow).convertTo(darker, CV_8UC3, 0.45);
  darker.copyTo(frame(shadow));
  frame(coat).convertTo(darker, CV_8UC3, 0.5);
  darker.copyTo(frame(coat));
  add_noise(frame, rng, 2.0);
  const cv::Mat a = plate_silhouette(frame, anywhere, SegmentOptions{});
  const cv::Mat f = plate_silhouette(frame, floor_only, SegmentOptions{});
  EXPECT_LT(cv::countNonZero(a(coat)), coat.area() / 10) << "shadows anywhere: the coat is lost";
  EXPECT_GT(cv::countNonZero(f(coat)), coat.area() * 95 / 100);
  EXPECT_LT(cv::countNonZero(f(shadow)), shadow.area() / 100) << "the floor's shadow is foreground";

  // Over the tiled floor, grey trousers as dark as a shadow hide the tiles' edges, which a
  // (soft-edged) shadow lets show through: where the tiles have edges to hide, the performer.
  cv::Mat frame2;
  cv::Mat light(kH, kW, CV_32F, cv::Scalar(1.0));
  light(shadow).setTo(0.45);
  cv::GaussianBlur(light, light, cv::Size(0, 0), 2.0);
  cv::Mat light3;
  cv::merge(std::vector<cv::Mat>{light, light, light}, light3);
  empty.convertTo(frame2, CV_32FC3);
  frame2 = frame2.mul(light3);
  frame2.convertTo(frame2, CV_8UC3);
  const cv::Rect trousers(14, 92, 32, 26);
  frame2(trousers).setTo(cv::mean(empty(trousers)) * 0.5);
  add_noise(frame2, rng, 2.0);
  const cv::Mat t = plate_silhouette(frame2, floor_only, SegmentOptions{});
  EXPECT_GT(cv::countNonZero(t(trousers)), trousers.area() / 2);
  EXPECT_LT(cv::countNonZero(t(shadow)), shadow.area() / 100) << "the floor's shadow is foreground";
}

// What one camera cannot tell from the plate: a dark shoe over the floor, of the floor's colour
// and darker by a shadow's factor, is background by the shadow rule. plate_silhouette names it
// among the pixels off the plate (for the other cameras to recover), and not the background
// the frame shows unchanged.
TEST(SegmentPlate, NamesThePixelsOffThePlateItLeftOut) {
  std::mt19937 rng(9);
  cv::Mat empty(kH, kW, CV_8UC3, cv::Scalar(150, 170, 190));  // a plain beige floor
  add_noise(empty, rng, 2.0);
  const PlateModel model = learn_plate(noisy_plates(empty, rng), "cam00");
  cv::Mat frame = empty.clone();
  frame(kPerformer).setTo(cv::Scalar(60, 60, 180));
  const cv::Rect shoe(40, 100, 20, 10);
  cv::Mat darker;
  frame(shoe).convertTo(darker, CV_8UC3, 0.5);
  darker.copyTo(frame(shoe));
  add_noise(frame, rng, 2.0);
  cv::Mat shadow_like, off_plate;
  const cv::Mat mask = plate_silhouette(frame, model, SegmentOptions{}, &shadow_like, &off_plate);
  ASSERT_LT(cv::countNonZero(mask(shoe)), shoe.area() / 10) << "the shoe is not lost here";
  EXPECT_GT(cv::countNonZero(off_plate(shoe)), shoe.area() * 95 / 100);
  cv::Mat plain = cv::Mat(kH, kW, CV_8U, cv::Scalar(255));
  plain(shoe).setTo(0);
  cv::Mat grown;
  cv::dilate(performer_mask(), grown, cv::Mat(), {-1, -1}, 3);
  plain.setTo(0, grown);
  EXPECT_LT(cv::countNonZero(off_plate & plain), cv::countNonZero(plain) / 50);
  EXPECT_EQ(cv::countNonZero(off_plate & mask), 0);
}

// The floor region of a camera of the ring: the floor under the rig's centre is in it, the wall
// above the horizon and the floor beyond the radius are not.
TEST(SegmentPlate, FloorShadowRegionIsTheFloorAroundTheCentre) {
  synth::RigOptions rig;
  rig.count = 4;
  rig.width = 160;
  rig.height_px = 120;
  rig.focal_px = 140;
  const Camera cam = synth::make_rig(rig).front();
  const Eigen::Vector3d centre(0, 0, 1);
  const cv::Mat region = floor_shadow_region(cam, centre, 2.0);
  ASSERT_EQ(region.size(), cv::Size(160, 120));
  Eigen::Vector2d px;
  ASSERT_TRUE(cam.project(Eigen::Vector3d(0, 0, 0), &px));
  EXPECT_EQ(region.at<std::uint8_t>(static_cast<int>(px.y()), static_cast<int>(px.x())), 255);
  ASSERT_TRUE(cam.project(Eigen::Vector3d(0, 0, 1.6), &px));  // level with the camera: the wall
  EXPECT_EQ(region.at<std::uint8_t>(static_cast<int>(px.y()), static_cast<int>(px.x())), 0);
  const Eigen::Vector3d far = -2.5 * cam.center().normalized();  // floor 2.5 m beyond the centre
  ASSERT_TRUE(cam.project(Eigen::Vector3d(far.x(), far.y(), 0), &px));
  if (cam.in_image(px)) {
    EXPECT_EQ(region.at<std::uint8_t>(static_cast<int>(px.y()), static_cast<int>(px.x())), 0);
  }
  EXPECT_EQ(cv::countNonZero(floor_shadow_region(cam, centre, 100.0)(cv::Rect(0, 0, 160, 1))), 0)
      << "the top row looks above the horizon";
}

TEST(SegmentMasks, AWrongSizeIsAnErrorNamingFileCameraAndFrame) {
  const fs::path dir = test::scratch_dir("segment_masks_size");
  const fs::path path = dir / "000007.png";
  write_image_atomic(path, cv::Mat::zeros(50, 60, CV_8U));
  try {
    read_supplied_mask(path, "cam05", kW, kH, 7);
    FAIL() << "a mask of the wrong size was accepted";
  } catch (const InputError& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find(path.string()), std::string::npos) << what;
    EXPECT_NE(what.find("cam05"), std::string::npos) << what;
    EXPECT_NE(what.find("frame 7"), std::string::npos) << what;
    EXPECT_NE(what.find("60x50"), std::string::npos) << what;
  }
  EXPECT_THROW(read_supplied_mask(dir / "missing.png", "cam05", kW, kH, 8), InputError);
  cv::Mat grey(kH, kW, CV_8U, cv::Scalar(0));
  grey(kPerformer).setTo(200);
  write_image_atomic(path, grey);
  EXPECT_DOUBLE_EQ(iou(read_supplied_mask(path, "cam05", kW, kH, 7), performer_mask()), 1.0);
}

TEST(SegmentMethod, AutoPrefersPlatesThenMasksThenChroma) {
  const fs::path root = test::scratch_dir("segment_auto");
  EXPECT_EQ(choose_method(root, "auto").method, "chroma");
  fs::create_directories(root / "masks" / "walk" / "cam00");
  EXPECT_EQ(choose_method(root, "auto").method, "masks");
  fs::create_directories(root / "plates");
  EXPECT_EQ(choose_method(root, "auto").method, "masks") << "an empty plates/ holds no plate";
  fs::create_directories(root / "plates" / "cam00");
  const MethodChoice choice = choose_method(root, "auto");
  EXPECT_EQ(choice.method, "plate");
  EXPECT_NE(choice.reason.find("plates/"), std::string::npos);
  EXPECT_EQ(choose_method(root, "chroma").method, "chroma");
}

// ---- the stage on a small session with supplied masks ---------------------------------------

// Silhouette of a vertical cylinder (radius 0.25 m, 1.7 m tall, at the origin) in `camera`:
// the pixels whose ray first meets it between heights `low` and `high`.
cv::Mat cylinder_silhouette(const Camera& camera, double low = 0.0, double high = 1.7) {
  cv::Mat m = cv::Mat::zeros(camera.intrinsics.height, camera.intrinsics.width, CV_8U);
  for (int y = 0; y < m.rows; ++y) {
    for (int x = 0; x < m.cols; ++x) {
      const Ray ray = camera.unproject({x + 0.5, y + 0.5});
      const Eigen::Vector2d o = ray.origin.head<2>(), d = ray.direction.head<2>();
      const double a = d.squaredNorm(), b = o.dot(d), c = o.squaredNorm() - 0.25 * 0.25;
      const double disc = b * b - a * c;
      if (a < 1e-12 || disc < 0) continue;
      const double t = (-b - std::sqrt(disc)) / a;
      const double z = ray.origin.z() + t * ray.direction.z();
      if (t > 0 && z > low && z < high) m.at<std::uint8_t>(y, x) = 255;
    }
  }
  return m;
}

class SegmentStage : public ::testing::Test {
 protected:
  void SetUp() override {
    root_ = test::scratch_dir("segment_stage");
    write_file_atomic(root_ / "session.yaml", "name: t\nfps: 10\n");
    synth::RigOptions rig;
    rig.count = 6;
    rig.width = kW;
    rig.height_px = kH;
    rig.focal_px = 140;
    cameras_ = synth::make_rig(rig);
    write_colmap_model(root_ / "calibration", cameras_);
    for (const Camera& cam : cameras_) {
      for (int f = 0; f < 2; ++f) {
        write_image_atomic(root_ / "capture" / "walk" / cam.name / (frame_name(f) + ".png"),
                           cv::Mat(kH, kW, CV_8UC3, cv::Scalar(90, 90, 90)));
        write_image_atomic(root_ / "masks" / "walk" / cam.name / (frame_name(f) + ".png"),
                           cylinder_silhouette(cam));
      }
    }
  }
  // Every camera's silhouette of the cylinder, and an empty mask per camera beside them.
  void cylinders(std::vector<cv::Mat>& silhouettes, std::vector<cv::Mat>& empty) const {
    for (const Camera& cam : cameras_) {
      silhouettes.push_back(cylinder_silhouette(cam));
      empty.push_back(cv::Mat::zeros(kH, kW, CV_8U));
    }
  }
  static cv::Mat lower_half() {
    cv::Mat lower = cv::Mat::zeros(kH, kW, CV_8U);
    lower(cv::Rect(0, kH / 2, kW, kH / 2)).setTo(255);
    return lower;
  }
  fs::path mask(const std::string& camera, int frame) const {
    return root_ / "masks" / "walk" / camera / (frame_name(frame) + ".png");
  }
  fs::path root_;
  std::vector<Camera> cameras_;
};

TEST_F(SegmentStage, ConsistentSilhouettesAreExplainedByTheOtherCameras) {
  ConsistencyCheck check(cameras_);
  ASSERT_TRUE(check.usable());
  std::vector<cv::Mat> silhouettes;
  for (const Camera& cam : cameras_) silhouettes.push_back(cylinder_silhouette(cam));
  for (double e : check.explained(silhouettes)) EXPECT_GT(e, 0.97);
  // A camera that keyed a piece of the backdrop as well: only it is flagged.
  cv::rectangle(silhouettes[2], cv::Rect(5, 5, 30, 30), 255, cv::FILLED);
  const std::vector<double> e = check.explained(silhouettes);
  for (std::size_t c = 0; c < e.size(); ++c) {
    if (c == 2) {
      EXPECT_LT(e[c], 0.8);
    } else {
      EXPECT_GT(e[c], 0.97) << c;
    }
  }
}

TEST_F(SegmentStage, OtherCamerasRecoverWhatOneTookForShadow) {
  ConsistencyCheck check(cameras_);
  std::vector<cv::Mat> silhouettes, doubtful;
  cylinders(silhouettes, doubtful);
  const cv::Mat truth = silhouettes[1].clone();
  // Camera 1 took the lower half of the performer for a shadow; and a shadow only it doubts.
  const cv::Mat lower = lower_half();
  doubtful[1] = truth & lower;
  silhouettes[1].setTo(0, lower);
  cv::rectangle(doubtful[1], cv::Rect(2, kH - 12, 30, 10), 255, cv::FILLED);
  ASSERT_LT(iou(silhouettes[1], truth), 0.8);
  check.recover(silhouettes, doubtful);
  EXPECT_GT(iou(silhouettes[1], truth), 0.97);
  EXPECT_EQ(cv::countNonZero(silhouettes[1](cv::Rect(2, kH - 12, 30, 10))), 0);
}

// Camouflage: camera 1 lost the performer's lower half where it matches the plate (off the
// plate's colour only by a little, so not surely background). The other cameras, pixel by pixel,
// give it back; not the background beside the performer, nor off-plate pixels no other camera
// sees the performer at.
TEST_F(SegmentStage, OtherCamerasRecoverACamouflagedPatch) {
  ConsistencyCheck check(cameras_);
  ASSERT_TRUE(check.usable());
  std::vector<cv::Mat> silhouettes, candidates;
  cylinders(silhouettes, candidates);
  const cv::Mat truth = silhouettes[1].clone();
  const cv::Mat lower = lower_half();
  silhouettes[1].setTo(0, lower);
  ASSERT_LT(iou(silhouettes[1], truth), 0.8);
  // Candidates: the lost half, a ring of background 2 to 4 px beside the performer, and a
  // patch of background away from it.
  cv::Mat near, beside;
  cv::dilate(truth, near, cv::getStructuringElement(cv::MORPH_ELLIPSE, {9, 9}));
  cv::dilate(truth, beside, cv::getStructuringElement(cv::MORPH_ELLIPSE, {3, 3}));
  const cv::Mat ring = near & ~beside;
  const cv::Rect away(2, kH - 14, 30, 10);
  candidates[1] = (truth & lower) | ring;
  candidates[1](away).setTo(255);
  check.recover_hidden(silhouettes, candidates, true);
  EXPECT_GT(iou(silhouettes[1], truth), 0.95);
  EXPECT_LT(cv::countNonZero(silhouettes[1] & ring), cv::countNonZero(ring) / 10)
      << "the background beside the performer taken";
  EXPECT_EQ(cv::countNonZero(silhouettes[1](away)), 0);
  // The other cameras are left as they were.
  for (std::size_t c = 0; c < cameras_.size(); ++c) {
    if (c == 1) continue;
    EXPECT_EQ(cv::countNonZero(silhouettes[c] != cylinder_silhouette(cameras_[c])), 0) << c;
  }
}

// The same camouflage (skin over a beige floor) often takes a hand from two cameras at once;
// each then dissents from the other's recovery. A camera that also left out an off-plate pixel
// there dissents only weakly, and one weak dissent is allowed - but not near the floor, where
// every camera leaves out the performer's shadow between the feet.
TEST_F(SegmentStage, TwoCamerasThatLostTheSamePartRecoverItAboveTheFloor) {
  ConsistencyCheck check(cameras_);
  ASSERT_TRUE(check.usable());
  std::vector<cv::Mat> silhouettes, candidates;
  cylinders(silhouettes, candidates);
  std::vector<cv::Mat> high(2), low(2);
  for (int c : {1, 2}) {
    high[c - 1] = cylinder_silhouette(cameras_[c], 1.0, 1.7);
    low[c - 1] = cylinder_silhouette(cameras_[c], 0.0, 0.25);
    silhouettes[c].setTo(0, high[c - 1] | low[c - 1]);
    candidates[c] = high[c - 1] | low[c - 1];
  }
  check.recover_hidden(silhouettes, candidates, true);
  for (int c : {1, 2}) {
    const int lost_high = cv::countNonZero(high[c - 1]), lost_low = cv::countNonZero(low[c - 1]);
    ASSERT_GT(lost_low, 50);
    EXPECT_GT(cv::countNonZero(silhouettes[c] & high[c - 1]), 0.9 * lost_high) << c;
    EXPECT_LT(cv::countNonZero(silhouettes[c] & low[c - 1]), 0.1 * lost_low) << c;
  }
}

TEST_F(SegmentStage, WarnsAboutAnEmptyAndAnInconsistentMaskNamingCameraAndFrame) {
  cv::Mat bad = cylinder_silhouette(cameras_[2]);
  cv::rectangle(bad, cv::Rect(5, 5, 30, 30), 255, cv::FILLED);
  write_image_atomic(mask("cam02", 0), bad);
  write_image_atomic(mask("cam04", 1), cv::Mat::zeros(kH, kW, CV_8U));
  const Session session = Session::open(root_);
  run_segment(session, StageArgs{});
  const nlohmann::json report = nlohmann::json::parse(read_file(root_ / "segment" / "report.json"));
  EXPECT_EQ(report["method"], "masks");
  ASSERT_EQ(report["warning_count"], 2) << report["warnings"].dump(1);
  const nlohmann::json& w = report["warnings"];
  EXPECT_EQ(w[0]["camera"], "cam02");
  EXPECT_EQ(w[0]["frame"], 0);
  EXPECT_EQ(w[0]["kind"], "inconsistent");
  EXPECT_EQ(w[1]["camera"], "cam04");
  EXPECT_EQ(w[1]["frame"], 1);
  EXPECT_EQ(w[1]["kind"], "foreground_fraction");
  // The masks are the stage's output as they were supplied.
  EXPECT_DOUBLE_EQ(iou(read_image(root_ / "segment" / "walk" / "cam00" / "000001.png",
                                  cv::IMREAD_GRAYSCALE),
                       cylinder_silhouette(cameras_[0])),
                   1.0);
}

TEST_F(SegmentStage, AMaskOfTheWrongSizeStopsTheStage) {
  write_image_atomic(mask("cam01", 1), cv::Mat::zeros(kH / 2, kW / 2, CV_8U));
  const Session session = Session::open(root_);
  try {
    run_segment(session, StageArgs{});
    FAIL() << "a mask of the wrong size was accepted";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("cam01 frame 1"), std::string::npos) << e.what();
  }
  EXPECT_FALSE(fs::exists(root_ / "segment" / "report.json"));
}

}  // namespace
}  // namespace fourd::segment
