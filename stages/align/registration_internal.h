#pragma once
// Internal to the registration (registration.h): the pieces its algorithm files share -
// closest-point matching (correspondences.cpp), the frame's tips as landmarks and the limb
// starts (landmarks.cpp), the embedded deformation graph (deformation_graph.cpp), its
// Gauss-Newton solver (gauss_newton.cpp) and the vertex-level ARAP refinement
// (arap_refinement.cpp). Not for other stages or files.
#include <Eigen/Core>
#include <Eigen/Geometry>
#include <Eigen/Sparse>
#include <cmath>
#include <memory>
#include <vector>

#include "pipeline/core/mesh.h"
#include "pipeline/geometry/rotation.h"
#include "pipeline/geometry/surface_query.h"
#include "stages/align/registration.h"

namespace fourd::align::detail {

using Vec3d = Eigen::Vector3d;
using Mat3d = Eigen::Matrix3d;
using Mat6 = Eigen::Matrix<double, 6, 6>;
using Vec6 = Eigen::Matrix<double, 6, 1>;
using SparseMatrix = Eigen::SparseMatrix<double>;

// ---- Small maths ----------------------------------------------------------------------------

inline Mat3d skew(const Vec3d& v) {
  Mat3d m;
  m << 0, -v.z(), v.y(), v.z(), 0, -v.x(), -v.y(), v.x(), 0;
  return m;
}

inline Mat3d rotation_from_vector(const Vec3d& w) {
  const double angle = w.norm();
  if (angle < 1e-12) return Mat3d::Identity();
  return Eigen::AngleAxisd(angle, w / angle).toRotationMatrix();
}

// Cauchy weight: down-weights outliers (wrong matches, topology merges) smoothly.
inline double robust_weight(double residual, double scale) {
  const double x = residual / scale;
  return 1.0 / (1.0 + x * x);
}

inline float cos_degrees(double degrees) { return static_cast<float>(std::cos(degrees * M_PI / 180.0)); }

// A factor that is `at_zero` at confidence 0, 1 at confidence 1, linear in between.
inline double by_confidence(double confidence, double at_zero) {
  return at_zero + (1 - at_zero) * confidence;
}

// The weight of frame surface of `confidence` (0..1).
inline double confidence_weight(double confidence, const RegistrationOptions& options) {
  return by_confidence(confidence, options.unconfident_weight);
}

// ---- Closest-point matches (correspondences.cpp) --------------------------------------------

struct Correspondence {
  Vec3d point = Vec3d::Zero();
  Vec3d normal = Vec3d::Zero();
  double weight = 0;  // 0: no match
  int triangle = -1;  // the frame triangle `point` is on
};

// Closest compatible surface points of every vertex, robustly weighted. `previous` (the same
// points' matches before they moved, or null) only speeds the search up.
std::vector<Correspondence> find_correspondences(const std::vector<Vec3f>& positions,
                                                 const std::vector<Vec3f>& normals,
                                                 const SurfaceQuery& target, double max_distance,
                                                 double robust_scale,
                                                 const RegistrationOptions& options,
                                                 const std::vector<Correspondence>* previous = nullptr);

// A frame point matched to the closest point of the deformed template (a barycentric point of
// one template triangle). The forward matches only pull the template onto surface it is
// already near; these pull it onto frame surface it has not reached yet (a limb that moved
// far), which the forward matches alone would leave uncovered.
struct ReverseMatch {
  Tri triangle = Tri::Zero();     // template vertices
  Vec3d barycentric = Vec3d::Zero();
  Vec3d point = Vec3d::Zero();    // the frame point
  Vec3d normal = Vec3d::Zero();   // the frame's unit normal there
  double weight = 0;              // 0: no match
  int face = -1;                  // the template triangle (index)
};

// The frame points the reverse matches start from: about one per template vertex, spread
// evenly over the frame's vertices, with their unit normals.
struct FrameSamples {
  std::vector<int> vertices;  // the frame vertex of each sample
  std::vector<Vec3f> points;
  std::vector<Vec3f> normals;
  std::vector<float> confidence;
};

// About `count` frame vertices spread evenly, with their normals and confidence.
FrameSamples sample_frame(const SurfaceQuery& target, std::size_t count);

// The deformed template as a surface to match frame points to, kept over the iterations of a
// fit: the first call builds its search tree, the later ones move its vertices and refit the
// tree (the same answers, at a fraction of a new tree's cost).
class FittedSurface {
 public:
  // The template deformed to `positions`.
  const SurfaceQuery& at(const TemplateModel& model, const std::vector<Vec3f>& positions);

 private:
  std::unique_ptr<SurfaceQuery> query_;
};

// Each sample's closest compatible point of the template deformed to `positions` (`fitted`
// holds it), robustly weighted. `previous` (the samples' matches to the template as it was
// before, or null) only speeds the search up.
std::vector<ReverseMatch> find_reverse_correspondences(
    const TemplateModel& model, const std::vector<Vec3f>& positions, const FrameSamples& samples,
    double max_distance, double robust_scale, const RegistrationOptions& options,
    FittedSurface* fitted, const std::vector<ReverseMatch>* previous = nullptr);

// rigid_icp (registration.h), leaving in `last_matches` the points' matches of its last
// iteration (to start the next search from).
Eigen::Isometry3d rigid_icp(const std::vector<Vec3f>& points, const std::vector<Vec3f>& normals,
                            const SurfaceQuery& target, int iterations, double max_distance,
                            const RegistrationOptions& options,
                            std::vector<Correspondence>* last_matches);

// The index of the position nearest `p` (-1 when there is none).
int nearest_vertex(const std::vector<Vec3f>& positions, const Vec3f& p);

// ---- Landmarks (landmarks.cpp) ----------------------------------------------------------------

// The frame's tips as landmarks for a fit. The tips are seen from the frame vertex nearest the
// template's centre in the fit. A covered frame tip with a template tip within anchor_distance
// anchors it; the others were missed by the fit - left uncovered, or covered without a template
// tip near (a limb that moved too far for closest points is left behind, or covered by
// stretched neighbouring surface) - and are matched to the remaining template tips.
struct TipLandmarks {
  std::vector<Landmark> landmarks;  // the anchors and the missed tips matched
  std::vector<int> frame_tips;      // the frame vertex of each landmark's point
  bool missed = false;              // a frame tip was missed and matched
  Mesh frame;                       // the frame's surface
  std::vector<std::vector<int>> frame_rings;
};

TipLandmarks tip_landmarks(const TemplateModel& model, const std::vector<Vec3f>& positions,
                           const SurfaceQuery& target, const RegistrationOptions& options);

// ---- The deformation graph (deformation_graph.cpp) ------------------------------------------

// Geodesic farthest-point sampling from vertex 0: each new sample is the vertex farthest from
// all samples so far (min(count, vertices) of them, in that order). `dist` receives every
// vertex's geodesic distance from its nearest sample, `owner` that sample's index (the geodesic
// Voronoi partition).
std::vector<int> farthest_point_samples(const Mesh& mesh, const std::vector<std::vector<int>>& rings,
                                        int count, std::vector<double>* dist,
                                        std::vector<int>* owner);

// Geodesic farthest-point nodes, edges between touching Voronoi cells, K blended influences
// per vertex (Sumner et al. 2007).
DeformationGraph build_graph(const Mesh& mesh, const std::vector<std::vector<int>>& rings,
                             int node_count, int influences);

// Cotangent weights of every one-ring edge, clamped positive (the template is remeshed
// isotropically, so few angles are obtuse).
std::vector<std::vector<double>> cotangent_weights(const Mesh& mesh,
                                                   const std::vector<std::vector<int>>& rings);

// Fills the model's softness (per vertex; per graph node, the smallest of the vertices it is
// nearest to, its own included) and softens the refinement's ring weights with it, to no less
// than crease_refine_floor. Needs the rings, their weights and the graph.
void soften_creases(const RegistrationOptions& options, TemplateModel* model);

// ---- Gauss-Newton on the graph (gauss_newton.cpp) ---------------------------------------------

// The graph energy's Gauss-Newton solver for one registration pass: the matrix's block pattern
// and the block Cholesky's ordering and factor pattern (block_cholesky.h) are computed once
// and reused by every step.
class GraphGaussNewton {
 public:
  // With `reverse_matches`, the pattern also holds the blocks the reverse matches need.
  GraphGaussNewton(const TemplateModel& model, bool reverse_matches);
  ~GraphGaussNewton();
  GraphGaussNewton(const GraphGaussNewton&) = delete;
  GraphGaussNewton& operator=(const GraphGaussNewton&) = delete;

  // One step of the graph energy (data both ways: `matches` of model.data_vertices, in their
  // order; landmarks; ARAP regulariser of weight `stiffness`); updates `state`'s rotations and
  // translations. False when the system could not be factorised or solved.
  bool step(const std::vector<Correspondence>& matches, const std::vector<ReverseMatch>& reverse,
            const std::vector<Landmark>& landmarks, double stiffness,
            const RegistrationOptions& options, DeformationState* state);

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

// ---- Vertex-level ARAP refinement (arap_refinement.cpp) ---------------------------------------

// Per-vertex rotations best mapping the template's one-rings onto `positions`.
std::vector<Mat3d> local_rotations(const TemplateModel& model, const std::vector<Vec3f>& positions);

// The symmetric cotangent Laplacian of the template's one-rings (model.ring_weights).
SparseMatrix laplacian(const TemplateModel& model);

// Vertex-level as-rigid-as-possible refinement towards the frame's surface (matched both ways),
// regularised against the template's own shape (Sorkine & Alexa 2007). The graph fit's last
// matches (`graph_matches` of model.data_vertices; `graph_reverse` of `graph_samples`) only
// speed up the first searches: every vertex starts from a data vertex's match near it, every
// frame sample from a graph sample's at or before its frame vertex.
void refine_vertices(const TemplateModel& model, const SurfaceQuery& target,
                     const RegistrationOptions& options,
                     const std::vector<Correspondence>& graph_matches,
                     const FrameSamples& graph_samples,
                     const std::vector<ReverseMatch>& graph_reverse,
                     std::vector<Vec3f>* positions);

}  // namespace fourd::align::detail
