#include "stages/import/meshes.h"

#include <fmt/format.h>

#include "pipeline/core/error.h"
#include "pipeline/core/mesh_io.h"
#include "pipeline/core/session.h"
#include "pipeline/geometry/measures.h"

namespace fourd::import {
namespace {

namespace fs = std::filesystem;

double diagonal(const Mesh& mesh) {
  Vec3f lo, hi;
  bounding_box(mesh, &lo, &hi);
  return mesh.positions.empty() ? 0.0 : static_cast<double>((hi - lo).norm());
}

}  // namespace

LengthUnit infer_mesh_unit(double d) {
  if (d <= 10) return LengthUnit::kMetre;
  if (d <= 500) return LengthUnit::kCentimetre;
  return LengthUnit::kMillimetre;
}

nlohmann::json MeshCheck::to_json() const {
  return {{"frames", frames},
          {"open_frames", open_frames},
          {"non_manifold_frames", non_manifold_frames},
          {"first_open", first_open},
          {"first_non_manifold", first_non_manifold}};
}

MeshImportResult import_meshes(const std::vector<fs::path>& files, const std::vector<TakeSpec>& takes,
                               const MeshImportOptions& options, const std::vector<fs::path>& take_dirs,
                               const fs::path& template_file) {
  if (files.empty()) throw InputError("--meshes: no .ply or .obj file");
  MeshImportResult result;
  std::optional<Mesh> first;
  fs::path first_file;
  double scale = 1;
  for (std::size_t k = 0; k < takes.size(); ++k) {
    const TakeSpec& take = takes[k];
    const int last = take.last < 0 ? static_cast<int>(files.size()) - 1 : take.last;
    if (last >= static_cast<int>(files.size()) || take.first >= static_cast<int>(files.size())) {
      throw InputError(fmt::format("--meshes: {} mesh files ({} ... {}), but take {} asks for frames {}:{}",
                                   files.size(), files.front().string(), files.back().string(), take.name,
                                   take.first, take.last < 0 ? std::string() : std::to_string(take.last)));
    }
    int frame = 0;
    for (int source = take.first; source <= last; source += take.step, ++frame) {
      const fs::path& file = files[static_cast<std::size_t>(source)];
      const std::string label = fmt::format("{}/{}", take.name, frame_name(frame));
      Mesh mesh = read_mesh(file);
      mesh.check(file.string());
      if (mesh.empty()) throw InputError(fmt::format("{} (take {} frame {}): the mesh has no triangles", file.string(), take.name, frame_name(frame)));
      if (!first) {
        const double d = diagonal(mesh);
        if (!options.units.empty()) {
          result.unit = parse_length_unit(options.units, "--mesh-units");
          result.unit_origin = "declared (--mesh-units)";
        } else {
          result.unit = infer_mesh_unit(d);
          result.unit_origin = fmt::format("inferred: the first mesh's bounding box diagonal is {:.4g} units", d);
        }
        scale = metres_per_unit(result.unit);
      }
      if (options.consistent && first) {
        if (mesh.num_vertices() != first->num_vertices() || mesh.triangles != first->triangles) {
          throw InputError(fmt::format(
              "{} (take {} frame {}): not the topology of the first frame {} ({} vertices and {} "
              "triangles against {} and {}): the sequence is not consistent (import it without "
              "--consistent, as reconstruct/)",
              file.string(), take.name, frame_name(frame), first_file.string(), mesh.num_vertices(),
              mesh.num_triangles(), first->num_vertices(), first->num_triangles()));
        }
      }
      const Eigen::Matrix3f rotation = options.world_rotation.cast<float>();
      for (Vec3f& p : mesh.positions) p = rotation * (p * static_cast<float>(scale));
      for (Vec3f& n : mesh.normals) n = rotation * n;
      mesh.uvs.clear();  // the texture is not imported: no dangling reference to it
      mesh.uv_triangles.clear();
      mesh.texture.clear();
      mesh.confidence.clear();  // no reconstruction confidence from another tool
      if (!first) {
        first = mesh;
        first_file = file;
        if (options.volume_centre) {
          Vec3f lo, hi;
          bounding_box(mesh, &lo, &hi);
          const Eigen::Vector3d centre = (0.5f * (lo + hi)).cast<double>();
          const double off = (centre - *options.volume_centre).head<2>().norm();
          if (off > 2.0) {
            result.warnings.push_back(fmt::format(
                "the first mesh ({}) is centred {:.2f} m (horizontally) from the cameras' common "
                "centre: wrong units (--mesh-units) or another world?",
                file.string(), off));
          }
        }
        if (options.consistent) write_ply(template_file, mesh);
      }
      const ManifoldReport manifold = check_manifold(mesh);
      ++result.check.frames;
      if (manifold.boundary_edges > 0) {
        if (result.check.open_frames++ == 0) result.check.first_open = label;
      }
      if (!manifold.manifold()) {
        if (result.check.non_manifold_frames++ == 0) result.check.first_non_manifold = label;
      }
      write_ply(take_dirs[k] / (frame_name(frame) + ".ply"), mesh);
    }
    result.frames[take.name] = frame;
  }
  if (result.check.open_frames > 0) {
    result.warnings.push_back(fmt::format("{} of {} meshes are open (have holes), first {}: align "
                                          "needs closed surfaces to measure their volume",
                                          result.check.open_frames, result.check.frames, result.check.first_open));
  }
  if (result.check.non_manifold_frames > 0) {
    result.warnings.push_back(fmt::format("{} of {} meshes are not manifold, first {}",
                                          result.check.non_manifold_frames, result.check.frames,
                                          result.check.first_non_manifold));
  }
  return result;
}

}  // namespace fourd::import
