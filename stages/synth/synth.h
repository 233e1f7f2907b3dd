#pragma once
// The synthetic studio stage: a performer with known geometry and motion, rendered from a
// virtual camera rig. Writes capture/, calibration/ and ground_truth/ of a session,
// deterministically from a seed.
#include <cstdint>
#include <string>
#include <vector>

#include "pipeline/core/config.h"
#include "pipeline/core/session.h"
#include "stages/common/stage.h"
#include "stages/synth/character.h"
#include "stages/synth/motion.h"
#include "stages/synth/render.h"

namespace fourd::synth {

// Perturbation of the calibration written to calibration/ (the images are rendered with the
// true cameras): lets the calibration check show that refinement recovers the truth.
struct CalibrationNoise {
  double rotation_deg = 0;
  double translation_mm = 0;
  double focal_pct = 0;
  template <class V>
  void visit(V& v) {
    v("rotation_deg", rotation_deg, "std-dev of a random rotation per camera [deg]",
      Range{0, 10});
    v("translation_mm", translation_mm, "std-dev of a random translation per camera [mm]",
      Range{0, 500});
    v("focal_pct", focal_pct, "std-dev of a relative focal-length error [%]", Range{0, 20});
  }
  bool any() const { return rotation_deg > 0 || translation_mm > 0 || focal_pct > 0; }
};

struct SynthOptions {
  std::uint64_t seed = 1;
  CharacterOptions character;  // the performer
  RigOptions rig;
  StudioOptions studio;
  CalibrationNoise calibration_noise;
  // A tuned value, not an option: each take's ground path centred on the capture volume (its
  // start_position ignored); false starts each take at its start_position.
  bool center_takes = true;
  // Size of the whole scene relative to the one described: performer, motion, rig and studio
  // together, as a studio filming a smaller subject puts its cameras closer. Pinhole images are
  // the same at any scale, so the capture is rendered at scale 1 and only what is metric is
  // scaled: the calibration, and the ground truth (meshes, template, skeleton, root paths and
  // the motions' parameters in metres).
  double scale = 1;
  std::vector<MotionSpec> takes;

  template <class V>
  void visit(V& v) {
    v("seed", seed, "random seed: every random choice derives from it (same seed, same bytes)");
    v("character", character, "the performer: body and clothing");
    v("rig", rig, "camera rig");
    v("studio", studio, "backdrop, noise, anti-aliasing");
    v("calibration_noise", calibration_noise, "error added to the written calibration");
    v("scale", scale,
      "size of the whole scene (performer, motion, rig) relative to the one described",
      Range{1e-3, 1e3});
    v("takes", takes, "the takes to perform and capture");
  }
  void check() const;
};

// Runs the stage on `session` (options from stages.synth of its session.yaml).
void run_synth(const Session& session, const StageArgs& args);

}  // namespace fourd::synth
