#pragma once
// Our depth maps handed to COLMAP: a dense workspace in COLMAP's format, fused by
// `colmap stereo_fusion` and meshed by `colmap poisson_mesher` (the Debian COLMAP has no CUDA,
// so its own patch_match_stereo cannot make the depth maps, but these two run on the CPU).
//
// Workspace layout (what stereo_fusion --workspace_format COLMAP --input_type geometric reads):
//   images/<camera>.png                              undistorted images (colours of the points)
//   sparse/cameras.txt, images.txt, points3D.txt      pinhole model; tie points whose tracks tell
//                                                    fusion which cameras overlap
//   stereo/depth_maps/<camera>.png.geometric.bin     depth along the optical axis [m], 0 = none
//   stereo/normal_maps/<camera>.png.geometric.bin    unit normals in camera coordinates
//   stereo/fusion.cfg                                the images to fuse
#include <filesystem>
#include <opencv2/core.hpp>
#include <string>
#include <vector>

#include "pipeline/core/config.h"
#include "pipeline/core/mesh.h"
#include "stages/reconstruct/pinhole.h"

namespace fourd::reconstruct {

// The options are the members visit() lists, with their help; the others are tuned values,
// not options (docs/reconstruct.md, "Advanced"); internal_lengths() lists the tuned lengths
// scaled to the subject.
struct ColmapMvsOptions {
  std::string executable = "colmap";
  int min_num_pixels = 2;             // stereo_fusion: pixels (views) a fused point needs
  double max_reproj_error = 2;        // stereo_fusion [px]
  double max_depth_error = 0.01;      // stereo_fusion: relative depth difference
  double max_normal_error = 20;       // stereo_fusion [deg]
  int poisson_depth = 9;              // poisson_mesher octree depth
  double poisson_trim = 5;            // poisson_mesher density trim
  double hull_trim = 0.005;           // faces more than this outside the hull are cut [m]
  double tie_tolerance = 0.01;        // depth maps agreeing this closely share a tie point [m]
  double normal_max_jump = 0.02;      // no normal across a depth jump larger than this [m]
  bool keep_workspace = false;        // keep the per-frame workspace (for inspection)
  double timeout_s = 300;             // a COLMAP command still running after this is killed
                                      // and rerun
  template <class V>
  void visit(V& v) {
    v("executable", executable, "colmap executable (name on PATH or path)");
  }
  template <class V>
  void internal_lengths(V& v) {
    v("hull_trim", hull_trim, "", Length{0, 1});
    v("tie_tolerance", tie_tolerance, "", Length{1e-6, 1});
    v("normal_max_jump", normal_max_jump, "", Length{1e-6, 1});
  }
};

struct MvsView {
  PinholeCamera camera;
  cv::Mat image;   // 8-bit BGR, undistorted to `camera`
  cv::Mat depth;   // CV_32F [m], 0 = none
  cv::Mat normal;  // CV_32FC3 unit normals in world coordinates (0 = none)
};

// Writes the workspace into `dir` (created). Tie points are sampled from the depth maps: a point
// joins the track of every other camera whose depth map agrees with it within `tie_tolerance`.
void write_colmap_workspace(const std::filesystem::path& dir, const std::vector<MvsView>& views,
                            double tie_tolerance = 0.01);

// Reads back a workspace's depth map of `camera` (tests and inspection).
cv::Mat read_workspace_depth(const std::filesystem::path& dir, const std::string& camera);

// Runs stereo_fusion on the workspace (writes fused.ply there); returns the number of fused
// points. Throws SolverError when COLMAP fails.
std::size_t colmap_stereo_fusion(const std::string& executable, const std::filesystem::path& dir,
                                 const ColmapMvsOptions& options);

// Runs poisson_mesher on <dir>/fused.ply and reads the mesh back. Throws SolverError when COLMAP
// fails.
Mesh colmap_poisson_mesh(const std::string& executable, const std::filesystem::path& dir,
                         const ColmapMvsOptions& options);

}  // namespace fourd::reconstruct
