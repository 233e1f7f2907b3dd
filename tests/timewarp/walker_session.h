#pragma once
// A session folder of walker takes in the align stage's layout (oracle/align/template.ply and
// oracle/align/<take>/<frame>.ply), for the timewarp and motionspace stage tests. The folder is
// removed with the object.
#include <fmt/format.h>
#include <stdlib.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <map>
#include <string>
#include <vector>

#include "pipeline/core/mesh_io.h"
#include "stages/common/stage.h"
#include "tests/timewarp/walker.h"

namespace fourd::test {

// Stage arguments that run a stage of the walker session in oracle mode.
inline StageArgs oracle_args(const std::filesystem::path& root) {
  StageArgs args;
  args.session_dir = root.string();
  args.oracle = true;
  return args;
}

class WalkerSession {
 public:
  WalkerSession() : walker_(make_walker()) {
    std::string pattern =
        (std::filesystem::temp_directory_path() / "fourd_walker_session_XXXXXX").string();
    if (::mkdtemp(pattern.data()) == nullptr) throw std::runtime_error("mkdtemp failed");
    root_ = pattern;
    std::filesystem::create_directories(align_dir());
    write_ply(align_dir() / "template.ply", mesh_of(walker_.mesh.positions));
  }
  ~WalkerSession() {
    std::error_code ec;
    std::filesystem::remove_all(root_, ec);
  }
  WalkerSession(const WalkerSession&) = delete;
  WalkerSession& operator=(const WalkerSession&) = delete;

  const std::filesystem::path& root() const { return root_; }
  std::filesystem::path align_dir() const { return root_ / "oracle" / "align"; }
  const Walker& walker() const { return walker_; }

  Mesh mesh_of(const Eigen::Matrix3Xd& x) const {
    Mesh m;
    m.positions = to_vec3f(x);
    m.triangles = walker_.mesh.triangles;
    return m;
  }

  void write_take(const std::string& take, const std::vector<Eigen::Matrix3Xd>& frames) {
    const std::filesystem::path dir = align_dir() / take;
    std::filesystem::remove_all(dir);
    std::filesystem::create_directories(dir);
    for (std::size_t f = 0; f < frames.size(); ++f) {
      write_ply(dir / fmt::format("{:06d}.ply", f), mesh_of(frames[f]));
    }
  }

  // session.yaml with the given motion-class lines (YAML flow mappings) and extra text.
  void write_config(const std::vector<std::string>& motions, const std::string& extra = "",
                    double fps = 25) {
    std::ofstream out(root_ / "session.yaml", std::ios::trunc);
    out << "name: walker\nfps: " << fps << "\nmotions:\n";
    for (const std::string& m : motions) out << "  - " << m << "\n";
    out << extra;
  }

  // Two walks (speed 1.0 and 1.6 m/s), two jumps (length 0.6 and 1.2 m) and the config.
  void write_standard() {
    WalkSpec slow;
    slow.cycle_frames = 15;
    slow.frames = 17;
    slow.start_phase = 0.1;
    slow.speed = 1.0;
    WalkSpec fast = slow;
    fast.amplitude = 0.5;
    fast.cycle_frames = 12;
    fast.frames = 14;
    fast.start_phase = 0.6;
    fast.speed = 1.6;
    walks["walk_slow"] = slow;
    walks["walk_fast"] = fast;
    write_take("walk_slow", walk_frames(walker_, slow));
    write_take("walk_fast", walk_frames(walker_, fast));
    JumpSpec short_jump;
    JumpSpec long_jump;
    long_jump.length = 1.2;
    long_jump.height = 0.25;
    write_take("jump_short", jump_frames(walker_, short_jump));
    write_take("jump_long", jump_frames(walker_, long_jump));
    write_config({"{name: locomotion, takes: [walk_slow, walk_fast], parameter: speed, cyclic: true}",
                  "{name: jump_length, takes: [jump_short, jump_long], parameter: length}"});
  }

  std::map<std::string, WalkSpec> walks;

 private:
  Walker walker_;
  std::filesystem::path root_;
};

}  // namespace fourd::test
