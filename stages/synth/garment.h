#pragma once
// A loose garment over the procedural performer (character.garment = skirt): a flared skirt
// sewn to the waist, its cloth simulated from the body's motion, so it swings behind the body,
// flares out in a spin and folds around a stepping leg, as skinning cannot make a surface do.
//
// The cloth is a grid of particles, rings from the waist down to the hem (position-based
// dynamics, many small steps per frame): the waist ring is skinned to the body, every other
// particle falls under gravity and air drag, held by distance constraints. Down the cloth the
// distances keep their cut length; along a ring and across a cell (shear) a distance may
// shrink to a third of its cut length (and no closer than the shell is thick), the cloth
// gathering where it hangs narrower than it is cut, but never stretch, so the cut's flare
// bounds how far out the skirt swings. A particle keeps thickness / 2 + clearance outside the
// implicit body the character was meshed from: its primitives carried rigidly by their joints,
// and as the skin nearest to the particle deforms (its blend of joint transforms), so the cloth
// stays off the skinned surface where joints bend. The folds of gathered cloth are not
// modelled (a gathered skirt is a smooth surface over them: along a ring the cloth turns by at
// most 45 degrees at a particle). The cloth collides with itself: a particle stays on its side
// of every triangle of the sheet that is not its neighbour, 2 shell thicknesses off it, so
// the shell does not pass through itself where the cloth folds onto itself (but for a few
// frames of a fast walk or spin, a small part of the skirt; tube_shell_positions thins the
// shell where the sheet comes nearer to itself than that).
//
// The surface is a closed shell `thickness` thick around the cloth's sheet (tube_shell_*:
// watertight, so ground truth re-meshes and inside tests work as for the body), with UVs into
// the performer's texture, the same topology in every frame.
#include <Eigen/Core>
#include <Eigen/Geometry>
#include <memory>
#include <vector>

#include "pipeline/core/mesh.h"
#include "pipeline/geometry/shell.h"
#include "stages/synth/body_model.h"
#include "stages/synth/character.h"

namespace fourd::synth {

struct Garment {
  TubeGrid grid;            // the cloth's particles: ring 0 sewn to the waist, the last the hem
  double thickness = 0;     // of the shell [m]
  double clearance = 0;     // least distance from the shell's inner side to the body [m]
  double flare = 0;         // half-angle of the cut's cone [rad]
  double length = 0;        // waist to hem along the cloth, as cut [m]
  double waist_radius = 0;  // mean horizontal distance of the waistband from the body's axis [m]
  // The cloth as cut, laid on the rest pose (a cone down from the waist): its rest lengths.
  std::vector<Eigen::Vector3d> cut;
  // Skinning of ring 0, the waistband: the influences of the body vertex nearest to it.
  std::vector<Eigen::Vector4i> waist_joints;
  std::vector<Eigen::Vector4f> waist_weights;
  // What the cloth collides with: the character's implicit body in its mesh's rest space.
  detail::BodyModel body;
  // The shell hanging still on the rest pose, with per-vertex UVs: the topology of every frame.
  Mesh rest;
};

// The skirt of `options` for a character whose skeleton, skin and height are final, its body
// `body` moved into the mesh's space (detail::moved_body). Lengths scale with the height.
std::shared_ptr<const Garment> make_skirt(const Character& character, const detail::BodyModel& body,
                                          const CharacterOptions& options);

// The cloth's particles through one take (exposed for tests; PerformerSurface is the user).
class ClothSimulation {
 public:
  // `character` must wear a garment and outlive the simulation.
  explicit ClothSimulation(const Character& character);
  ~ClothSimulation();
  ClothSimulation(const ClothSimulation&) = delete;
  ClothSimulation& operator=(const ClothSimulation&) = delete;

  // Starts a take whose first frame has joints `world_from_joint`: the cloth as cut, hanging
  // on the rest pose placed where the frame's pelvis is, then carried into the frame's pose
  // and left to come to rest (2.4 s of simulated time; a take starting in motion starts with
  // its skirt still).
  void start(const std::vector<Eigen::Isometry3d>& world_from_joint);
  // Simulates `seconds` while the joints move from the last frame's to `world_from_joint`
  // (rotations interpolated spherically, positions linearly).
  void advance(const std::vector<Eigen::Isometry3d>& world_from_joint, double seconds);
  // The sheet's particles, garment.grid order.
  const std::vector<Eigen::Vector3d>& positions() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

// The performer's surface through one take, frame by frame: the skinned body and the garment
// simulated from its motion (the garment's vertices after the body's). Cloth remembers: the
// frames of a take come in order, a new take needs a new PerformerSurface. Without a garment a
// frame is skin_mesh's, bit for bit.
class PerformerSurface {
 public:
  PerformerSurface(const Character& character, double fps);
  ~PerformerSurface();
  Mesh next(const Pose& pose);

 private:
  const Character& character_;
  double fps_;
  std::unique_ptr<ClothSimulation> cloth_;
  bool started_ = false;
};

// The performer's surface at rest: the skin's rest mesh and the garment hanging on it (the
// topology of every frame of PerformerSurface).
Mesh rest_surface(const Character& character);

// The garment's shell for the sheet `sheet` (positions and the rest mesh's UVs and triangles).
Mesh garment_surface(const Garment& garment, const std::vector<Eigen::Vector3d>& sheet);

}  // namespace fourd::synth
