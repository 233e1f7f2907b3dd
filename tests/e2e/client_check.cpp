// What the real-client tests (Blender, three.js in Chromium) compare against fourd's own output.
//
//   client_check positions ASSET PLY CLIENT.json MAX_MM
//     CLIENT.json's "positions" (the client's evaluated world vertices of one frame, glTF axes,
//     in the .glb's vertex order; "compressed": true for a --compress export) against
//     fourd-play's mesh of the same frame (PLY, our axes): the .glb's vertex i copies the
//     template vertex glb_vertices(...).source[i]. Prints max / mean difference in mm; exits 1
//     above MAX_MM.
//   client_check meshes A.ply B.ply MAX_MM
//     Two meshes of the same vertices (e.g. a frame of fourd-export --sequence and fourd-play's
//     mesh of that frame): max / mean vertex distance in mm, same triangles; exits 1 above MAX_MM.
//   client_check frames MESH_DIR CLIENT.json MAX_MM
//     CLIENT.json's "frames" (frame indices) and "positions" (the world vertices of each of those
//     frames, our axes and vertex order, one frame after the other: the web player's script run)
//     against fourd-play's meshes MESH_DIR/frame_NNNNN.ply of the same script. Prints max / mean
//     difference in mm over all of them; exits 1 above MAX_MM.
//   client_check camera CALIBRATION N WIDTH HEIGHT OUT.json
//     Studio camera N of a COLMAP calibration at WIDTH x HEIGHT as three.js needs it: the
//     OpenGL projection matrix and the camera's world matrix in glTF axes (column-major).
//   client_check image FOURD.png CLIENT.png MIN_DB [DIFF.png]
//     PSNR of the client's render (RGBA, the character opaque on a transparent background)
//     against fourd-play's render of the same frame and camera, over the pixels the client's
//     character covers; also the PSNR over the whole image after laying the client's
//     character over fourd's background. Exits 1 below MIN_DB.
#include <fmt/format.h>

#include <Eigen/Geometry>
#include <cmath>
#include <fstream>
#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <string>
#include <vector>

#include "pipeline/core/colmap_model.h"
#include "pipeline/core/error.h"
#include "pipeline/core/files.h"
#include "pipeline/core/mesh_io.h"
#include "pipeline/gltf/gltf.h"
#include "pipeline/render/textured_render.h"
#include "runtime/asset.h"
#include "runtime/gltf_export.h"

namespace {

using namespace fourd;

int positions(const std::string& asset_path, const std::string& ply, const std::string& client,
              double max_mm) {
  const Asset asset = load_asset(asset_path);
  GlbOptions options;
  const nlohmann::json j = nlohmann::json::parse(read_file(client));
  options.compress = j.value("compressed", false);
  const gltf::ExportVertices vertices = glb_vertices(asset_template(asset), options);
  const Mesh frame = read_ply(ply);
  const std::vector<double> p = j.at("positions").get<std::vector<double>>();
  if (p.size() != 3 * vertices.source.size())
    throw InputError(fmt::format("{}: {} vertices, the .glb has {}", client, p.size() / 3,
                                 vertices.source.size()));
  double max_error = 0, sum = 0;
  std::size_t worst = 0;
  for (std::size_t i = 0; i < vertices.source.size(); ++i) {
    const Eigen::Vector3d ours =
        gltf::kOurFromGltf * Eigen::Vector3d(p[3 * i], p[3 * i + 1], p[3 * i + 2]);
    const double e =
        1e3 * (ours - frame.positions.at(vertices.source[i]).cast<double>()).norm();
    if (e > max_error) worst = i;
    max_error = std::max(max_error, e);
    sum += e;
  }
  fmt::print("{} ({}) vs fourd's mesh {}: {} vertices, max difference {:.4f} mm (vertex {}), mean "
             "{:.4f} mm (tolerance {} mm)\n",
             j.value("client", "client"), client, ply, vertices.source.size(), max_error, worst,
             sum / vertices.source.size(), max_mm);
  return max_error <= max_mm ? kExitOk : kExitFailure;
}

int meshes(const std::string& a_path, const std::string& b_path, double max_mm) {
  const Mesh a = read_mesh(a_path), b = read_mesh(b_path);
  if (a.num_vertices() != b.num_vertices() || a.triangles != b.triangles)
    throw InputError(fmt::format("{} has {} vertices / {} triangles, {} {} / {} (or other "
                                 "triangles)", a_path, a.num_vertices(), a.num_triangles(),
                                 b_path, b.num_vertices(), b.num_triangles()));
  double max_error = 0, sum = 0;
  for (std::size_t v = 0; v < a.num_vertices(); ++v) {
    const double e = 1e3 * (a.positions[v] - b.positions[v]).norm();
    max_error = std::max(max_error, e);
    sum += e;
  }
  fmt::print("{} vs {}: {} vertices, max difference {:.4f} mm, mean {:.4f} mm (tolerance {} mm)\n",
             a_path, b_path, a.num_vertices(), max_error, sum / a.num_vertices(), max_mm);
  return max_error <= max_mm ? kExitOk : kExitFailure;
}

int frames(const std::string& mesh_dir, const std::string& client, double max_mm) {
  const nlohmann::json j = nlohmann::json::parse(read_file(client));
  const std::vector<int> indices = j.at("frames").get<std::vector<int>>();
  const std::vector<double> p = j.at("positions").get<std::vector<double>>();
  if (indices.empty()) throw InputError(fmt::format("{}: no frames", client));
  if (p.size() % (3 * indices.size()) != 0)
    throw InputError(fmt::format("{}: {} coordinates for {} frames", client, p.size(), indices.size()));
  const std::size_t vertices = p.size() / (3 * indices.size());
  double max_error = 0, sum = 0;
  int worst_frame = -1;
  for (std::size_t k = 0; k < indices.size(); ++k) {
    const std::string ply = fmt::format("{}/frame_{:05d}.ply", mesh_dir, indices[k]);
    const Mesh mesh = read_ply(ply);
    if (mesh.num_vertices() != vertices)
      throw InputError(fmt::format("{} has {} vertices, {} reports {}", ply, mesh.num_vertices(),
                                   client, vertices));
    for (std::size_t v = 0; v < vertices; ++v) {
      const double* q = &p[3 * (k * vertices + v)];
      const double e = 1e3 * (Eigen::Vector3d(q[0], q[1], q[2]) -
                              mesh.positions[v].cast<double>()).norm();
      if (e > max_error) worst_frame = indices[k];
      max_error = std::max(max_error, e);
      sum += e;
    }
  }
  fmt::print("{} ({}) vs fourd-play's meshes in {}: {} frames of {} vertices, max difference "
             "{:.6f} mm (frame {}), mean {:.6f} mm (tolerance {} mm)\n",
             j.value("client", "client"), client, mesh_dir, indices.size(), vertices, max_error,
             worst_frame, sum / (indices.size() * vertices), max_mm);
  return max_error <= max_mm ? kExitOk : kExitFailure;
}

nlohmann::json column_major(const Eigen::Matrix4d& m) {
  std::vector<double> v(m.data(), m.data() + 16);  // Eigen is column-major
  return v;
}

int camera(const std::string& calibration, int index, int width, int height,
           const std::string& out) {
  const std::vector<Camera> cameras = read_colmap_model(calibration);
  const Camera& cam = cameras.at(index);
  Intrinsics in = cam.intrinsics;
  const double sx = static_cast<double>(width) / in.width, sy = static_cast<double>(height) / in.height;
  const double fx = in.fx * sx, fy = in.fy * sy, cx = in.cx * sx, cy = in.cy * sy;
  const double n = 0.05, f = 100;
  Eigen::Matrix4d projection;
  projection << 2 * fx / width, 0, 1 - 2 * cx / width, 0,  //
      0, 2 * fy / height, 2 * cy / height - 1, 0,          //
      0, 0, -(f + n) / (f - n), -2 * f * n / (f - n),      //
      0, 0, -1, 0;
  // OpenGL camera (y up, looking down -z) -> OpenCV camera -> our world -> glTF axes.
  const Eigen::Matrix4d flip = Eigen::Vector4d(1, -1, -1, 1).asDiagonal();
  Eigen::Matrix4d to_gltf = Eigen::Matrix4d::Identity();
  to_gltf.topLeftCorner<3, 3>() = gltf::kOurFromGltf.transpose();
  const Eigen::Matrix4d world = to_gltf * cam.camera_from_world.inverse().matrix() * flip;
  nlohmann::json j;
  j["camera"] = cam.name;
  j["width"] = width;
  j["height"] = height;
  j["projection"] = column_major(projection);
  j["matrix_world"] = column_major(world);
  write_file_atomic(out, j.dump(1));
  fmt::print("camera {} ({}) at {}x{} -> {}\n", index, cam.name, width, height, out);
  return kExitOk;
}

int image(const std::string& ours_path, const std::string& client_path, double min_db,
          const std::string& diff_path) {
  const cv::Mat ours = cv::imread(ours_path, cv::IMREAD_COLOR);
  const cv::Mat client = cv::imread(client_path, cv::IMREAD_UNCHANGED);
  if (ours.empty() || client.empty() || client.channels() != 4)
    throw InputError(fmt::format("{} or {} (RGBA) is not a readable image", ours_path, client_path));
  if (ours.size() != client.size())
    throw InputError(fmt::format("{} is {}x{}, {} is {}x{}", ours_path, ours.cols, ours.rows,
                                 client_path, client.cols, client.rows));
  cv::Mat mask, client_bgr, composite;
  cv::extractChannel(client, mask, 3);
  mask = mask > 0;
  cv::cvtColor(client, client_bgr, cv::COLOR_BGRA2BGR);
  ours.copyTo(composite);
  client_bgr.copyTo(composite, mask);
  cv::Mat client_float, composite_float;
  client_bgr.convertTo(client_float, CV_32FC3, 1 / 255.0);
  composite.convertTo(composite_float, CV_32FC3, 1 / 255.0);
  const double character = image_error(client_float, ours, mask).psnr_db();
  const cv::Mat all(ours.size(), CV_8UC1, cv::Scalar(255));
  const double whole = image_error(composite_float, ours, all).psnr_db();
  const double cover = static_cast<double>(cv::countNonZero(mask)) / mask.total();
  if (!diff_path.empty()) {  // |difference| x 4 over the client's character, for a look
    cv::Mat diff;
    cv::absdiff(client_bgr, ours, diff);
    diff.setTo(cv::Scalar::all(0), ~mask);
    cv::imwrite(diff_path, diff * 4);
  }
  fmt::print("{} vs {}: PSNR {:.2f} dB over the client's character ({:.2f}% of the image), "
             "{:.2f} dB over the whole image on fourd's background (threshold {} dB)\n",
             client_path, ours_path, character, 100 * cover, whole, min_db);
  if (cover == 0) return kExitFailure;
  return character >= min_db ? kExitOk : kExitFailure;
}

}  // namespace

int main(int argc, char** argv) {
  const std::vector<std::string> a(argv + 1, argv + argc);
  try {
    if (a.size() == 5 && a[0] == "positions") return positions(a[1], a[2], a[3], std::stod(a[4]));
    if (a.size() == 4 && a[0] == "meshes") return meshes(a[1], a[2], std::stod(a[3]));
    if (a.size() == 4 && a[0] == "frames") return frames(a[1], a[2], std::stod(a[3]));
    if (a.size() == 6 && a[0] == "camera")
      return camera(a[1], std::stoi(a[2]), std::stoi(a[3]), std::stoi(a[4]), a[5]);
    if ((a.size() == 4 || a.size() == 5) && a[0] == "image")
      return image(a[1], a[2], std::stod(a[3]), a.size() == 5 ? a[4] : "");
  } catch (const std::exception& e) {
    fmt::print(stderr, "client_check: {}\n", e.what());
    return kExitFailure;
  }
  fmt::print(stderr,
             "usage: client_check positions ASSET PLY CLIENT.json MAX_MM\n"
             "       client_check meshes A.ply B.ply MAX_MM\n"
             "       client_check frames MESH_DIR CLIENT.json MAX_MM\n"
             "       client_check camera CALIBRATION N WIDTH HEIGHT OUT.json\n"
             "       client_check image FOURD.png CLIENT.png MIN_DB [DIFF.png]\n");
  return kExitUsage;
}
