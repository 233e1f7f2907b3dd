#pragma once
// The align validator's measurements, exposed for tests (validate_align() in validate.h uses
// them on align/ and align_oracle/).
#include <filesystem>
#include <string>
#include <vector>

namespace fourd::validate {

struct AlignedFrameError {
  std::string take;
  int frame = 0;
  std::vector<double> correspondence;  // per template vertex [m]
  std::vector<double> surface;         // per template vertex [m]; empty when not measured
  std::vector<int> flipped;  // triangles turned over relative to the ground truth (indices)
};

struct AlignmentErrors {
  std::string root;  // "<take>/<frame>" the template was bound at
  int rebound = 0;   // template vertices whose closest truth point at the root tore from their
                     // neighbours' (two parts touching there), bound to their neighbours' part
  std::vector<Tri> triangles;             // the template's
  std::vector<AlignedFrameError> frames;  // sorted by take, frame
  double correspondence_rms = 0;  // over every vertex of every frame [m]
  double correspondence_p95 = 0;  // [m]
  double surface_rms = 0;         // [m]
  int flipped = 0;                // over all frames
  int flipped_distinct = 0;       // template triangles flipped in at least one frame
  // Per flip, the largest correspondence error of the triangle's vertices: its median [m]
  // (tens of mm: the surface slid along itself, e.g. across a crease; a few mm: folds).
  double flipped_error_median = 0;
  void summarise();  // fills the totals from `frames`
};

// Measures the aligned meshes <align_dir>/<take>/<frame>.ply (template <align_dir>/template.ply,
// root frame from <align_dir>/tree.json) against the ground-truth meshes
// <truth_meshes>/<take>/<frame>.ply (one consistent topology): each template vertex is bound to
// its closest ground-truth surface point at the root frame (barycentric on that frame's mesh),
// or, where that point is on another part of the truth than its neighbours' (parts touching at
// the root), to the closest point on its neighbours' part; and followed through the ground truth; with `with_surface`, also the distance of each
// aligned vertex to the input surface <input_dir>/<take>/<frame>.ply. Frames are read from
// `frames_dir` (default: align_dir; e.g. align_dir/sequential for the baseline).
AlignmentErrors measure_alignment(const std::filesystem::path& align_dir,
                                  const std::filesystem::path& input_dir,
                                  const std::filesystem::path& truth_meshes, bool with_surface,
                                  const std::filesystem::path& frames_dir = {});

}  // namespace fourd::validate
