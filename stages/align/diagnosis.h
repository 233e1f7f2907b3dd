#pragma once
// Self-diagnosis of aligned frames. The template is cut into patches of about equal geodesic
// size (farthest-point seeds, each vertex to its geodesically nearest seed: no assumption of a
// limb structure, a skirt is patches like any other surface), and every fit is measured patch
// by patch:
//  - residual: template vertices to the frame's surface (a patch left off the surface);
//  - uncovered: the frame surface nearest the patch that the fit does not reach (a limb of the
//    frame the template did not follow);
//  - stretch: rms relative change of the patch's template edges (a patch pulled across a gap
//    or onto another limb);
//  - flips: template triangles folded over;
//  - jump: how far the patch is from the mean of its take neighbours' fits, over the take's
//    typical value for that patch (a patch that slid along the surface in one frame: the
//    surface cues cannot see it, the motion can).
// Each cue has a limit relative to the template's size (its largest extent: scale-free); a patch over a limit is
// named in the frame's verdict.
#include <string>
#include <vector>

#include "pipeline/geometry/surface_query.h"
#include "stages/align/registration.h"

namespace fourd::align {

struct TemplateRegions {
  std::vector<int> of_vertex;           // region of every template vertex
  std::vector<std::string> names;       // "r<k> <where>": its place on the template at rest
  std::vector<Eigen::Vector3d> centre;  // rest-pose centroid of each region
};

// `count` patches of the template (fewer if it has fewer vertices).
TemplateRegions make_regions(const TemplateModel& model, int count);

// One patch of one fit.
struct RegionCues {
  double residual_p90 = 0;  // template vertices to the frame surface, 90th percentile [m]
  double uncovered = 0;     // fraction of the frame surface nearest this patch not reached
  double stretch_rms = 0;   // rms relative edge-length change
  int flipped = 0;          // folded triangles (any vertex in the patch)
  double jump = -1;         // mean distance to the mean of the take neighbours' fits [m]; -1: no
                            // aligned neighbour on both sides
  double jump_ratio = 0;    // jump over the take's median jump of this patch
};

// The surface cues of one fit of `positions` to `target` (jump left at -1).
std::vector<RegionCues> region_cues(const TemplateModel& model, const TemplateRegions& regions,
                                    const std::vector<Vec3f>& positions, const SurfaceQuery& target,
                                    double coverage_distance);

// Mean per-patch distance of `positions` to the midpoint of `before` and `after`.
std::vector<double> region_jumps(const TemplateRegions& regions, const std::vector<Vec3f>& positions,
                                 const std::vector<Vec3f>& before, const std::vector<Vec3f>& after);

// The limits for a template of largest extent `size` [m].
struct DiagnosisLimits {
  double residual = 0;
  double uncovered = 0;
  double stretch = 0;
  int flipped = 0;
  double jump = 0;        // [m] a jump below this is never wrong
  double jump_ratio = 0;  // ... and one must also be this many times the take's median
};
DiagnosisLimits diagnosis_limits(double size);

struct RegionVerdict {
  int region = -1;
  std::string cue;  // residual | uncovered | stretch | flipped | jump
  double value = 0;
  double limit = 0;
};

// The patches over a limit (worst first, by value over limit).
std::vector<RegionVerdict> judge(const std::vector<RegionCues>& cues, const DiagnosisLimits& limits);

// Whether a patch jumps from the midpoint of its take neighbours by more than `factor` x the
// jump limit (and over the limit's ratio to the take's median): a limb fitted to the other one,
// not a fast limb (align.md, item 6).
bool jumps_far(const std::vector<RegionCues>& cues, const DiagnosisLimits& limits, double factor);

// A frame's badness for choosing between fits: the largest value/limit over patches and cues
// (the jump's only where it is also over jump_ratio x the take's median); over 1: judged wrong.
double badness(const std::vector<RegionCues>& cues, const DiagnosisLimits& limits);

}  // namespace fourd::align
