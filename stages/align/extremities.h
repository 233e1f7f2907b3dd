#pragma once
// Extremities of a body surface - the tips of its protrusions: head, hands, feet - and their
// matching between the template and a frame. Geodesic distance along the surface from a point
// on the trunk hardly changes when limbs articulate, and its local maxima are the limbs' tips.
// Matched tips are landmarks that pull a limb which moved too far for closest-point matching
// (an arm raised from the side to the front between two frames) onto the right surface.
#include <Eigen/Core>
#include <vector>

#include "pipeline/core/config.h"
#include "pipeline/core/mesh.h"

namespace fourd::align {

// Tuned values, not options (docs/align.md, "Advanced"); internal_lengths() lists the lengths
// scaled to the subject.
struct ExtremityOptions {
  double radius = 0.3;          // a tip is the farthest vertex within this geodesic radius [m]
                                // (more than a foot's length: a heel is no tip)
  double min_fraction = 0.5;    // ... at least this fraction of the farthest vertex's distance
  int max_count = 8;            // the farthest tips kept (a person has 5: head, hands, feet;
                                // a hoofed animal 8: four hooves, head, tail, two ears)
  double tolerance = 0.6;       // matched tips' geodesic distances differ by at most this
                                // fraction of the template's
  double min_tolerance = 0.08;  // ... or this [m]
  double max_match_distance = 1.5;  // matched tips farther apart are not matched [m]
  double anchor_distance = 0.1;     // a covered frame tip anchors the template tip this near [m]
  template <class V>
  void internal_lengths(V& v) {
    v("radius", radius, "", Length{1e-05, 100});
    v("min_tolerance", min_tolerance, "", Length{0, 100});
    v("max_match_distance", max_match_distance, "", Length{0, 1000});
    v("anchor_distance", anchor_distance, "", Length{0, 100});
  }
};

struct Extremities {
  int centre = -1;                // the vertex geodesic distances are measured from
  std::vector<int> vertices;      // tips, farthest first
  std::vector<double> geodesic;   // their geodesic distance from the centre [m]
};

// The tips of `mesh` seen from vertex `centre`. `rings`: neighbours of every vertex.
Extremities find_extremities(const Mesh& mesh, const std::vector<std::vector<int>>& rings,
                             int centre, const ExtremityOptions& options);

// A template tip matched to a frame tip.
struct TipMatch {
  int template_tip = -1;  // index into the template's Extremities
  int frame_tip = -1;     // index into the frame's
};

// Pairs template tips (now at `template_positions`) with frame tips (at `frame_positions`) of
// compatible geodesic distance, one to one: as many pairs as possible, then the smallest sum of
// distances between the paired positions.
std::vector<TipMatch> match_extremities(const Extremities& templ,
                                        const std::vector<Eigen::Vector3d>& template_positions,
                                        const Extremities& frame,
                                        const std::vector<Eigen::Vector3d>& frame_positions,
                                        const ExtremityOptions& options);

// The template tip that a frame tip the fit covers anchors: among the template tips not
// `used`, at most `anchor_distance` from the frame tip (`at`) and whose limb roots are at most
// that from the frame limb's root (`root`), the one whose root is nearest. Not the nearest tip:
// a fit can drag one foot onto the other leg, and the root (hip, shoulder), which hardly moves,
// still tells whose foot it is. -1 when none qualifies.
int anchored_tip(const std::vector<Eigen::Vector3d>& template_tips,
                 const std::vector<Eigen::Vector3d>& template_roots, const std::vector<char>& used,
                 const Eigen::Vector3d& at, const Eigen::Vector3d& root, double anchor_distance);

}  // namespace fourd::align
