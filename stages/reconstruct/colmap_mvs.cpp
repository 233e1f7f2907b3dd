#include "stages/reconstruct/colmap_mvs.h"

#include <Eigen/Geometry>
#include <fmt/format.h>

#include "pipeline/core/error.h"
#include "pipeline/core/files.h"
#include "pipeline/core/image_io.h"
#include "pipeline/core/mesh_io.h"
#include "stages/reconstruct/colmap_tool.h"

namespace fourd::reconstruct {
namespace {

namespace fs = std::filesystem;

std::string image_name(const MvsView& view) { return view.camera.name + ".png"; }

// COLMAP's fusion back-projects pixel (col, row) of a depth map with K as is, i.e. it puts pixel
// centres at integers; our K puts them at +0.5. Shifting the principal point by -0.5 makes the
// workspace's rays those of our pixel centres.
Eigen::Matrix3d workspace_k(const PinholeCamera& cam) {
  Eigen::Matrix3d k = cam.K;
  k(0, 2) -= 0.5;
  k(1, 2) -= 0.5;
  return k;
}

struct TiePoint {
  Eigen::Vector3d position;
  std::vector<std::pair<int, Eigen::Vector2d>> track;  // (view, pixel in the workspace's K)
};

std::vector<TiePoint> tie_points(const std::vector<MvsView>& views, double tolerance) {
  constexpr int kStep = 12;  // sample every kStep-th pixel of each depth map
  std::vector<TiePoint> points;
  for (std::size_t i = 0; i < views.size(); ++i) {
    const MvsView& v = views[i];
    for (int r = kStep / 2; r < v.depth.rows; r += kStep) {
      for (int c = kStep / 2; c < v.depth.cols; c += kStep) {
        const float d = v.depth.at<float>(r, c);
        if (d <= 0) continue;
        TiePoint tp;
        tp.position = v.camera.unproject(c + 0.5, r + 0.5, d);
        for (std::size_t j = 0; j < views.size(); ++j) {
          const PinholeCamera& cam = views[j].camera;
          Eigen::Vector3d pc = cam.to_camera(tp.position);
          if (pc.z() <= 0) continue;
          Eigen::Vector2d px = cam.pixel(pc);
          if (!cam.in_image(px)) continue;
          float dj = views[j].depth.at<float>(static_cast<int>(px.y()), static_cast<int>(px.x()));
          if (j != i && !(dj > 0 && std::abs(dj - pc.z()) < tolerance)) continue;
          tp.track.emplace_back(static_cast<int>(j), px - Eigen::Vector2d(0.5, 0.5));
        }
        if (tp.track.size() >= 2) points.push_back(std::move(tp));
      }
    }
  }
  return points;
}

void write_sparse_model(const fs::path& dir, const std::vector<MvsView>& views,
                        const std::vector<TiePoint>& points) {
  std::string cameras = "# CAMERA_ID MODEL WIDTH HEIGHT PARAMS[]\n";
  for (std::size_t i = 0; i < views.size(); ++i) {
    const PinholeCamera& c = views[i].camera;
    Eigen::Matrix3d k = workspace_k(c);
    cameras += fmt::format("{} PINHOLE {} {} {:.17g} {:.17g} {:.17g} {:.17g}\n", i + 1, c.width,
                           c.height, k(0, 0), k(1, 1), k(0, 2), k(1, 2));
  }
  // Observations per view: (pixel, point id); index in this list = POINT2D_IDX.
  std::vector<std::vector<std::pair<Eigen::Vector2d, std::size_t>>> observations(views.size());
  std::string points3d = "# POINT3D_ID X Y Z R G B ERROR TRACK[] as (IMAGE_ID, POINT2D_IDX)\n";
  for (std::size_t p = 0; p < points.size(); ++p) {
    const TiePoint& tp = points[p];
    std::string track;
    for (const auto& [view, px] : tp.track) {
      track += fmt::format(" {} {}", view + 1, observations[view].size());
      observations[view].emplace_back(px, p + 1);
    }
    points3d += fmt::format("{} {:.9g} {:.9g} {:.9g} 128 128 128 0{}\n", p + 1, tp.position.x(),
                            tp.position.y(), tp.position.z(), track);
  }
  std::string images = "# IMAGE_ID QW QX QY QZ TX TY TZ CAMERA_ID NAME\n# POINTS2D[] as (X, Y, POINT3D_ID)\n";
  for (std::size_t i = 0; i < views.size(); ++i) {
    const PinholeCamera& c = views[i].camera;
    Eigen::Quaterniond q(c.R);
    images += fmt::format("{} {:.17g} {:.17g} {:.17g} {:.17g} {:.17g} {:.17g} {:.17g} {} {}\n", i + 1,
                          q.w(), q.x(), q.y(), q.z(), c.t.x(), c.t.y(), c.t.z(), i + 1,
                          image_name(views[i]));
    std::string line;
    for (const auto& [px, id] : observations[i]) {
      line += fmt::format("{}{:.3f} {:.3f} {}", line.empty() ? "" : " ", px.x(), px.y(), id);
    }
    images += line + "\n";
  }
  ensure_directory(dir);
  write_file_atomic(dir / "cameras.txt", cameras);
  write_file_atomic(dir / "images.txt", images);
  write_file_atomic(dir / "points3D.txt", points3d);
}

}  // namespace

void write_colmap_workspace(const fs::path& dir, const std::vector<MvsView>& views,
                            double tie_tolerance) {
  ensure_directory(dir / "images");
  ensure_directory(dir / "stereo" / "depth_maps");
  ensure_directory(dir / "stereo" / "normal_maps");
  std::string cfg;
  for (const MvsView& v : views) {
    const std::string name = image_name(v);
    write_image_atomic(dir / "images" / name, v.image, {cv::IMWRITE_PNG_COMPRESSION, 1});
    write_colmap_array(dir / "stereo" / "depth_maps" / (name + ".geometric.bin"), v.depth);
    // Normals in camera coordinates, as COLMAP stores them.
    cv::Mat normal_cam(v.normal.size(), CV_32FC3);
    const Eigen::Matrix3f r = v.camera.R.cast<float>();
    for (int y = 0; y < v.normal.rows; ++y) {
      const cv::Vec3f* in = v.normal.ptr<cv::Vec3f>(y);
      cv::Vec3f* out = normal_cam.ptr<cv::Vec3f>(y);
      for (int x = 0; x < v.normal.cols; ++x) {
        Eigen::Vector3f n = r * Eigen::Vector3f(in[x][0], in[x][1], in[x][2]);
        out[x] = cv::Vec3f(n.x(), n.y(), n.z());
      }
    }
    write_colmap_array(dir / "stereo" / "normal_maps" / (name + ".geometric.bin"), normal_cam);
    cfg += name + "\n";
  }
  write_file_atomic(dir / "stereo" / "fusion.cfg", cfg);
  write_sparse_model(dir / "sparse", views, tie_points(views, tie_tolerance));
}

cv::Mat read_workspace_depth(const fs::path& dir, const std::string& camera) {
  return read_colmap_array(dir / "stereo" / "depth_maps" / (camera + ".png.geometric.bin"));
}

std::size_t colmap_stereo_fusion(const std::string& executable, const fs::path& dir,
                                 const ColmapMvsOptions& options) {
  const fs::path fused = dir / "fused.ply";
  run_colmap_checked(
      executable, "stereo_fusion",
      {"--workspace_path", dir.string(), "--workspace_format", "COLMAP", "--input_type",
       "geometric", "--output_type", "PLY", "--output_path", fused.string(),
       "--StereoFusion.min_num_pixels", std::to_string(options.min_num_pixels),
       "--StereoFusion.max_reproj_error", fmt::format("{}", options.max_reproj_error),
       "--StereoFusion.max_depth_error", fmt::format("{}", options.max_depth_error),
       "--StereoFusion.max_normal_error", fmt::format("{}", options.max_normal_error),
       "--StereoFusion.num_threads", "1"},
      dir / "colmap.log", options.timeout_s);
  return read_ply(fused).positions.size();
}

Mesh colmap_poisson_mesh(const std::string& executable, const fs::path& dir,
                         const ColmapMvsOptions& options) {
  const fs::path meshed = dir / "meshed.ply";
  run_colmap_checked(executable, "poisson_mesher",
                     {"--input_path", (dir / "fused.ply").string(), "--output_path",
                      meshed.string(), "--PoissonMeshing.depth",
                      std::to_string(options.poisson_depth), "--PoissonMeshing.trim",
                      fmt::format("{}", options.poisson_trim), "--PoissonMeshing.num_threads",
                      "1"},
                     dir / "colmap.log", options.timeout_s);
  Mesh mesh = read_ply(meshed);
  mesh.normals.clear();
  mesh.colors.clear();
  return mesh;
}

}  // namespace fourd::reconstruct
