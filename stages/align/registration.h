#pragma once
// Pairwise non-rigid registration of the template to one frame's surface.
//
// Coarse to fine:
//  1. rigid point-to-plane ICP;
//  2. an embedded deformation graph (Sumner et al. 2007): nodes sampled on the template by
//     geodesic farthest-point sampling, each with a rotation and a translation; every vertex
//     follows a blend of its nearest nodes (by geodesic distance, so an arm resting on the body
//     never moves with it). Gauss-Newton on closest-point (point-to-plane + a little
//     point-to-point, normal-compatible, robustly weighted) matches both ways - each template
//     vertex to the frame, and frame points to the deformed template, which pulls the template
//     onto frame surface it has not reached yet (a limb that moved far) - and
//     as-rigid-as-possible graph terms, with the regulariser relaxed level by level and softened
//     in the template's concave creases (armpits, crotch: where parts of the body meet and skin
//     stretches as the joint opens); the sparse (6x6-block) Cholesky's ordering
//     and factor pattern are computed once and reused by every iteration;
//  3. a vertex-level as-rigid-as-possible refinement (Sorkine & Alexa 2007) towards the
//     surface (matched both ways too), regularised against the template's own shape, so detail never accumulates
//     errors along the tree.
// When the fit leaves more than a little of the frame uncovered - a limb moved too far for
// closest points - the frame's tips (head, hands, feet: extremities of the geodesic distance
// from the trunk) become landmarks (the missed ones matched to free template tips by where
// their limbs attach, so that a left foot is not taken for a right one that crossed it; the
// covered ones anchoring theirs) and the registration runs again: from the same start when a
// tip was missed, from the start with every landmark's limb first turned as a whole about its
// joint towards its tip (turn_limbs_to_tips), and from the start with every landmark's limb
// bent along the frame's surface (bend_limbs_along_frame; that fit skips the coarse levels,
// whose stiff regulariser would straighten the bends). A retry is kept when it fits clearly
// closer than the first fit; of the retries about as close as the closest, the least stretched
// wins (a limb bent at the wrong joint can cover the frame too, but only by stretching the
// template).
// Deformations are always expressed relative to the template at rest, so registering frame
// after frame along the tree composes nothing but the starting guess.
//
// One file per algorithm, sharing registration_internal.h: registration.cpp (rigid ICP, the
// passes and the choice among retries, the fit's measures), correspondences.cpp (closest
// points both ways), deformation_graph.cpp (the graph and the template model),
// gauss_newton.cpp (the graph's solver), arap_refinement.cpp (the vertex-level refinement and
// unfolding), landmarks.cpp (the frame's tips and the limb starts).
#include <Eigen/Core>
#include <Eigen/Geometry>
#include <string>
#include <vector>

#include "pipeline/core/config.h"
#include "pipeline/core/mesh.h"
#include "pipeline/geometry/surface_query.h"
#include "stages/align/extremities.h"

namespace fourd::align {

// The options are the members visit() lists, with their help; the others are tuned values,
// not options (docs/align.md, "Advanced"); internal_lengths() lists the tuned lengths scaled to
// the subject.
struct RegistrationOptions {
  int graph_nodes = 250;
  int node_influences = 4;    // nodes blended per vertex
  int rigid_iterations = 10;  // rigid ICP iterations before the non-rigid fit
  std::vector<double> stiffness = {8, 4, 1.5, 0.5, 0.08};  // graph regulariser weight per level
  int iterations_per_level = 5;  // Gauss-Newton iterations per level
  int graph_samples = 4000;      // template vertices whose matches drive the graph (and the
                                 // rigid fit): a larger template is sampled evenly to this many
                                 // (TemplateModel::data_vertices), so that a pass costs about
                                 // the same at any resolution (the graph has graph_nodes nodes
                                 // whatever the template's); the refinement moves every vertex
  double max_distance = 0.25;    // correspondences farther are ignored, first level [m]
  double final_max_distance = 0.06;  // ... last level and refinement [m]
  double normal_angle = 60;      // largest angle between matched normals [deg]
  double robust_scale = 0.01;    // Cauchy scale of the residuals [m]
  double point_to_point = 0.1;   // point-to-point weight relative to point-to-plane
  double reverse_weight = 1.0;   // frame-to-template matches, relative to template-to-frame
  int refine_iterations = 6;     // vertex-level ARAP refinement iterations (0: none)
  double refine_weight = 0.5;    // data weight of the refinement relative to ARAP stiffness
  double coverage_distance = 0.03;  // a frame point farther from the fit is uncovered [m]
  double landmark_weight = 300;  // weight of one matched tip, in template vertices' data terms
                                 // (0: no landmarks)
  int landmark_levels = 5;       // levels that use the landmarks
  double landmark_gain = 0.7;    // a retry with landmarks is kept only below this x the
                                 // first fit's both-ways rms
  double landmark_uncovered = 0.002;  // tips are looked at only when the first fit leaves more
                                      // of the frame than this uncovered
  double limb_fraction = 0.6;
  double limb_blend = 0.05;      // a turned limb's rotation fades in over this [m]
  double limb_band = 0.04;       // a limb is followed along the frame in rings this wide [m]
  int bent_first_level = 4;      // the fit from the limbs bent along the frame starts here
  double crease_curvature = 0.5; // regulariser softened to 1 / (1 + H / this) where the
                                 // template is concave with mean curvature H [1/m] (0: uniform);
                                 // an inverse length, divided by the subject's scale factor
  double crease_refine_floor = 0.25;  // ... but the vertex refinement's to no less than this
  int unfold_rings = 2;  // folds the refinement leaves get the graph's shape back, with this
                         // many rings around them (-1: not)
  double unconfident_weight = 0.3;  // weight of frame surface of confidence 0 (Mesh::confidence)
                                    // relative to confidence 1
  double unconfident_stiffness = 0.2;  // regulariser factor where the template's own surface
                                       // had confidence 0 (its root frame's membranes)
  double stretch_tolerance = 1.5;  // retries within this x the closest fit's both-ways rms:
                                   // the least stretched is kept ...
  double stretch_margin = 0.9;     // ... if it is stretched less than this x the closest one
  ExtremityOptions extremities;

  template <class V>
  void visit(V& v) {
    v("graph_nodes", graph_nodes, "deformation graph nodes", Range{4, 100000});
    v("limb_fraction", limb_fraction,
      "when a fit leaves part of the frame uncovered, the limbs (the template's surface "
      "geodesically nearer a tip than this x the tip's distance from the trunk) are turned about "
      "their joints towards the frame's tips and the frame registered again (0: no such retry; "
      "faster on coarse frames)",
      Range{0, 1});
  }
  template <class V>
  void internal_lengths(V& v) {
    v("max_distance", max_distance, "", Length{1e-06, 100});
    v("final_max_distance", final_max_distance, "", Length{1e-06, 100});
    v("robust_scale", robust_scale, "", Length{1e-07, 100});
    v("coverage_distance", coverage_distance, "", Length{1e-06, 100});
    v("limb_blend", limb_blend, "", Length{0, 100});
    v("limb_band", limb_band, "", Length{1e-05, 10});
    v("extremities", extremities, "");
  }
  void check() const;
};

// The embedded deformation graph of the template.
struct DeformationGraph {
  std::vector<int> node_vertex;                     // #M template vertex of each node
  std::vector<Eigen::Vector3d> node_position;       // #M rest positions [m]
  std::vector<std::vector<int>> node_neighbours;    // #M graph edges (both directions)
  int influences = 0;                               // K slots per vertex
  std::vector<int> influence_node;                  // #V*K, -1 in unused slots
  std::vector<double> influence_weight;             // #V*K, summing to 1 per vertex
};

// Everything registration needs about the template; built once, shared read-only by every
// registration (thread-safe).
struct TemplateModel {
  Mesh rest;                                      // the template (positions, triangles)
  std::vector<std::vector<int>> rings;            // one-ring of every vertex
  std::vector<std::vector<double>> ring_weights;  // cotangent weights x crease softness
  DeformationGraph graph;
  Extremities extremities;  // its tips, from the vertex nearest its centroid
  // Per tip: every vertex's geodesic distance from it over the template at rest [m] (a limb is
  // the part nearer its tip than a length; the same for every frame).
  std::vector<std::vector<double>> tip_distance;
  // The regulariser's factor in (0, 1]: per vertex (crease_curvature) and per graph node (the
  // smallest of the vertices it moves most); an edge takes the smaller of its ends' (in the
  // refinement, at least crease_refine_floor: ring_weights include it).
  std::vector<double> vertex_softness;
  std::vector<double> node_softness;
  // The vertices whose matches drive the graph and the rigid fit, in increasing order: all of
  // them up to graph_samples vertices, else graph_samples spread evenly over the surface
  // (geodesic farthest points).
  std::vector<int> data_vertices;
};

TemplateModel build_template_model(const Mesh& template_mesh, const RegistrationOptions& options);

// A deformation of the template: per graph node a rotation and translation (the node at rest
// position g moves a point x to R (x - g) + g + t), and the final vertex positions after the
// refinement.
struct DeformationState {
  std::vector<Eigen::Matrix3d> rotation;     // #M
  std::vector<Eigen::Vector3d> translation;  // #M
  std::vector<Vec3f> positions;              // #V
};

DeformationState rest_state(const TemplateModel& model);
// Vertex positions the graph alone produces.
std::vector<Vec3f> deform_with_graph(const TemplateModel& model, const DeformationState& state);
// Applies the rigid motion after the deformation: x -> motion * x, for graph and positions.
void apply_rigid(const TemplateModel& model, const Eigen::Isometry3d& motion,
                 DeformationState* state);

// The triangles of a deformed template folded over: normal against the rest normal carried by
// the local (one-ring) rotations.
std::vector<int> folded_triangles(const TemplateModel& model, const std::vector<Vec3f>& positions);

// Where `positions` (the vertex refinement's) fold the surface over, gives the folds and `rings`
// rings around them the graph's shape back: the refinement's displacement from
// `graph_positions` is interpolated harmonically (cotangent weights) from the patch's border,
// so the patch joins the rest and takes the graph's smooth layout. Kept only if it has fewer
// folds. rings < 0: nothing done.
void unfold(const TemplateModel& model, const std::vector<Vec3f>& graph_positions, int rings,
            std::vector<Vec3f>* positions);

// How well a deformed template fits a frame.
struct FitStats {
  double surface_rms = 0;        // template vertices to the frame's surface [m], weighted by
                                 // the surface's confidence as registration weights it
  double surface_p95 = 0;        // [m]
  double surface_max = 0;        // [m]
  double reverse_rms = 0;        // frame vertices to the fitted surface [m] (weighted so too)
  double uncovered_fraction = 0; // frame vertices farther than coverage_distance from the fit
                                 // (so weighted)
  int flipped_triangles = 0;     // triangles turned over relative to their local rotation
  double stretch_rms = 0;        // rms relative change of the template's edge lengths
};

FitStats evaluate_fit(const TemplateModel& model, const std::vector<Vec3f>& positions,
                      const SurfaceQuery& target, const RegistrationOptions& options);

// Both-ways rms distance between a fitted template and its frame [m].
double two_sided_rms(const FitStats& s);

// Of several fits of one frame (not empty), the one to keep: of the fits whose both-ways rms is
// within `stretch_tolerance` x the closest's, the least stretched, if its stretch is below
// `stretch_margin` x the closest's; else the closest. A limb on the other limb or bent at the
// wrong joint can cover the frame about as closely, but only by stretching the template; two
// fits stretched about as much are told apart by how closely they fit.
std::size_t least_stretched_close_fit(const std::vector<FitStats>& fits, double stretch_tolerance,
                                      double stretch_margin);

// Rigid point-to-plane ICP of `points` (with their unit normals) onto the target; returns the
// motion to apply to them.
Eigen::Isometry3d rigid_icp(const std::vector<Vec3f>& points, const std::vector<Vec3f>& normals,
                            const SurfaceQuery& target, int iterations, double max_distance,
                            const RegistrationOptions& options);

// A template tip held at a frame point.
struct Landmark {
  int vertex = -1;                                   // template vertex (a tip)
  Eigen::Vector3d point = Eigen::Vector3d::Zero();   // the frame's matched tip
};

// The start of the articulated retry: every limb whose tip is a landmark is turned as a whole
// about its joint so that the tip points at the landmark's point. A limb is the template's
// surface geodesically nearer its tip than `limb_fraction` x the tip's distance from the
// trunk's centre (model.extremities); its joint is the mean of its border, where it is cut
// off; the turn fades in over `blend` [m] of geodesic distance from the border. Closest points
// and the graph's regulariser then bend the limb where it has a joint, instead of where the
// surface first lets them (an arm raised far between two frames stays down at the shoulder and
// bends at the elbow).
DeformationState turn_limbs_to_tips(const TemplateModel& model, const DeformationState& start,
                                    const std::vector<Landmark>& landmarks, double limb_fraction,
                                    double blend);

// The other start of the articulated retry: every limb whose tip is a landmark follows the
// frame's surface. On the template and on the frame (from `frame_tips`, the frame vertex of each
// landmark), the rings of equal geodesic distance from the tip, `band` [m] wide, have centres
// along the limb's axis, wherever it bends (geodesic distance hardly changes when a limb
// articulates). Every graph node of the limb moves with its ring: turned as the axis turns
// there, moved as its centre moves. The limb is followed as far as the frame's rings are about
// as wide as the template's (a wider ring has run into the body); the last ring's motion fades
// out from there to the limb's border. A knee bent between two frames is bent in the start.
DeformationState bend_limbs_along_frame(const TemplateModel& model, const DeformationState& start,
                                        const std::vector<Landmark>& landmarks,
                                        const std::vector<int>& frame_tips, const Mesh& frame,
                                        const std::vector<std::vector<int>>& frame_rings,
                                        double limb_fraction, double band);

// What a registration tried beyond its first fit.
struct RegistrationTrace {
  std::vector<std::string> retries;  // the retries run
  std::string kept;                  // the retry kept; empty: the first fit
};

// Registers the template, starting from `start` (e.g. the parent frame's deformation moved by
// a rigid guess), to the target surface. `trace`, when given, receives the retries it ran.
DeformationState register_to_surface(const TemplateModel& model, const DeformationState& start,
                                     const SurfaceQuery& target,
                                     const RegistrationOptions& options,
                                     RegistrationTrace* trace = nullptr);

// The template's triangles over `positions` (a fit as a mesh).
Mesh fitted_mesh(const TemplateModel& model, const std::vector<Vec3f>& positions);

// Area-weighted vertex normals of positions over the template's triangles.
std::vector<Vec3f> vertex_normals(const std::vector<Vec3f>& positions,
                                  const std::vector<Tri>& triangles);

}  // namespace fourd::align
