#include "stages/validate/oracle_inputs.h"

#include <fmt/format.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <random>

#include "pipeline/core/error.h"
#include "pipeline/core/files.h"
#include "pipeline/core/log.h"
#include "pipeline/core/mesh_io.h"
#include "pipeline/core/staged_folder.h"
#include "pipeline/geometry/solid.h"

namespace fourd::validate {
namespace {

namespace fs = std::filesystem;

std::vector<fs::path> sorted_entries(const fs::path& dir, bool directories, const std::string& ext) {
  std::vector<fs::path> out;
  std::error_code ec;
  if (!fs::is_directory(dir, ec)) return out;
  for (const auto& e : fs::directory_iterator(dir)) {
    const std::string name = e.path().filename().string();
    if (name.empty() || name.front() == '.') continue;
    if (directories ? e.is_directory() : (e.is_regular_file() && e.path().extension() == ext)) {
      out.push_back(e.path());
    }
  }
  std::sort(out.begin(), out.end());
  return out;
}

// Copies every regular file under `from` to the same relative path under `to`.
void copy_tree(const fs::path& from, const fs::path& to) {
  ensure_directory(to);
  fs::copy(from, to, fs::copy_options::recursive | fs::copy_options::overwrite_existing);
}

// A seed per (take, frame) so every frame gets its own grid offset, reproducibly.
unsigned frame_seed(int seed, const std::string& take, const std::string& frame) {
  return static_cast<unsigned>(hash_bytes(take + "/" + frame, static_cast<std::uint64_t>(seed)));
}

}  // namespace

void prepare_oracle_inputs(const Session& session, const OracleOptions& options) {
  const fs::path truth = session.ground_truth_dir();
  const fs::path meshes = truth / "meshes";
  if (!fs::is_directory(meshes)) {
    throw InputError(fmt::format("{}: no ground-truth meshes; oracle inputs need a synthetic "
                                 "session (run fourd-synth first)",
                                 meshes.string()));
  }
  const fs::path target = session.dir("oracle");
  StagedFolder staged(target);
  const fs::path& staging = staged.path();
  {
    // segment: the ground-truth silhouettes, in segment/'s layout <take>/<camera>/<frame>.png.
    if (fs::is_directory(truth / "silhouettes")) {
      copy_tree(truth / "silhouettes", staging / "segment");
    } else {
      log::warn("{}: no ground-truth silhouettes; oracle/segment is not written",
                (truth / "silhouettes").string());
    }
    // align: the ground truth in its consistent topology.
    copy_tree(meshes, staging / "align");
    fs::copy_file(truth / "template.ply", staging / "align" / "template.ply",
                  fs::copy_options::overwrite_existing);

    // reconstruct: every frame re-meshed with fresh connectivity.
    struct Item {
      std::string take;
      fs::path file;
    };
    std::vector<Item> items;
    for (const fs::path& take : sorted_entries(meshes, true, "")) {
      for (const fs::path& file : sorted_entries(take, false, ".ply")) {
        items.push_back({take.filename().string(), file});
      }
    }
    if (items.empty()) throw InputError(fmt::format("{}: no <take>/<frame>.ply", meshes.string()));
    log::Progress progress("re-meshing ground truth with fresh connectivity", items.size());
    tbb::parallel_for(std::size_t{0}, items.size(), [&](std::size_t i) {
      const Item& item = items[i];
      const unsigned seed = frame_seed(options.seed, item.take, item.file.stem().string());
      std::mt19937 rng(seed);
      std::uniform_real_distribution<double> fraction(0.05, 0.95);
      const Eigen::Vector3d offset =
          options.remesh_voxel * Eigen::Vector3d(fraction(rng), fraction(rng), fraction(rng));
      Mesh mesh = read_ply(item.file);
      mesh.check(item.file.string());
      const Mesh fresh = remesh_fresh(mesh, options.remesh_voxel, offset, options.noise_sigma, seed);
      write_ply(staging / "reconstruct" / item.take / item.file.filename(), fresh);
      progress.step();
    });
    YAML::Emitter used;
    used << to_yaml(options);
    write_file_atomic(staging / "options.yaml", std::string(used.c_str()) + "\n");

    staged.commit();  // replaces oracle/ as a whole
    log::info("wrote {}: {} frames re-meshed (voxel {:.1f} mm, noise {:.1f} mm)", target.string(),
              items.size(), 1e3 * options.remesh_voxel, 1e3 * options.noise_sigma);
  }
}

}  // namespace fourd::validate
