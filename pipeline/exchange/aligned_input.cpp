#include "pipeline/exchange/aligned_input.h"

#include <fmt/format.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <regex>

#include "pipeline/core/error.h"
#include "pipeline/core/mesh_io.h"
#include "pipeline/core/session.h"

namespace fourd {

namespace {

// Frame numbers of <dir>/<take>/NNNNNN.ply, which must run 0, 1, 2, ... without a gap.
int count_frames(const std::filesystem::path& take_dir, const std::string& take) {
  if (!std::filesystem::is_directory(take_dir)) {
    throw InputError(fmt::format("take {}: no aligned frames ({} is missing)", take,
                                 take_dir.string()));
  }
  static const std::regex kFrameFile(R"((\d{6})\.ply)");
  std::vector<int> frames;
  for (const auto& entry : std::filesystem::directory_iterator(take_dir)) {
    std::smatch m;
    const std::string name = entry.path().filename().string();
    if (std::regex_match(name, m, kFrameFile)) frames.push_back(std::stoi(m[1]));
  }
  std::sort(frames.begin(), frames.end());
  if (frames.empty()) {
    throw InputError(fmt::format("take {}: no frames in {}", take, take_dir.string()));
  }
  for (int i = 0; i < static_cast<int>(frames.size()); ++i) {
    if (frames[i] != i) {
      throw InputError(fmt::format("take {}: frame {} is missing in {}", take, frame_name(i),
                                   take_dir.string()));
    }
  }
  return static_cast<int>(frames.size());
}

}  // namespace

AlignedInput open_aligned_input(const std::filesystem::path& dir) {
  const std::filesystem::path path = dir / "template.ply";
  if (!std::filesystem::exists(path)) {
    throw InputError(fmt::format(
        "no aligned meshes: {} is missing (run fourd-align first, or use --oracle after "
        "fourd-validate --prepare-oracle)",
        path.string()));
  }
  AlignedInput input;
  input.dir = dir;
  input.template_mesh = read_ply(path);
  input.template_mesh.check(path.string());
  if (input.template_mesh.empty()) {
    throw InputError(fmt::format("{}: the template has no triangles", path.string()));
  }
  return input;
}

std::vector<Eigen::Matrix3Xd> load_take(const AlignedInput& input, const std::string& take) {
  const std::filesystem::path take_dir = input.dir / take;
  const int n = count_frames(take_dir, take);
  const Mesh& templ = input.template_mesh;
  std::vector<Eigen::Matrix3Xd> frames(n);
  tbb::parallel_for(0, n, [&](int f) {
    const std::filesystem::path path = take_dir / (frame_name(f) + ".ply");
    const std::string what = fmt::format("take {} frame {} ({})", take, frame_name(f), path.string());
    Mesh mesh;
    try {
      mesh = read_ply(path);
    } catch (const InputError& e) {  // e.g. a non-finite coordinate: say which take and frame
      throw InputError(fmt::format("take {} frame {}: {}", take, frame_name(f), e.what()));
    }
    if (mesh.num_vertices() != templ.num_vertices()) {
      throw InputError(fmt::format("{}: {} vertices, the template has {}", what,
                                   mesh.num_vertices(), templ.num_vertices()));
    }
    if (!mesh.triangles.empty() && mesh.triangles != templ.triangles) {
      throw InputError(fmt::format("{}: its triangles differ from the template's (another topology)",
                                   what));
    }
    mesh.check(what);  // names the first non-finite vertex
    frames[f] = positions_matrix(mesh).cast<double>();
  });
  return frames;
}

}  // namespace fourd
