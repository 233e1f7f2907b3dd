// The headless player (runtime/player.h) and the fourd-play executable: control scripts,
// outputs, and bad input (malformed scripts, truncated assets).
#include "runtime/player.h"

#include <gtest/gtest.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>
#include <tuple>
#include <algorithm>

#include "pipeline/core/error.h"
#include "pipeline/core/files.h"
#include "tests/graph/test_graph.h"
#include "tests/scratch_dir.h"

namespace fourd {
namespace {

namespace fs = std::filesystem;

const fs::path& test_asset() {
  static const fs::path file = [] {
    const fs::path d = test::scratch_dir("asset");
    Asset a;
    a.graph = test::make_test_graph(true);
    save_asset(d / "motion_graph.fourd", a);
    return d / "motion_graph.fourd";
  }();
  return file;
}

std::string parse_error(const std::string& text) {
  try {
    parse_control_script(text, "s.txt");
  } catch (const InputError& e) {
    return e.what();
  }
  return "";
}

TEST(ControlScript, ParsesEveryCommand) {
  const ControlScript s = parse_control_script(
      "# a comment\n"
      "fps 25\n"
      "duration 4.5   # seconds\n"
      "start locomotion 1.2 0.3\n"
      "at 2.0 motion jump_length 0.9 0.4\n"
      "at 1.0 param 1.5\n"
      "at 3 turn -20\n"
      "at 3.5 walk 1.3 90\n"
      "at 4 jump 1.0\n"
      "at 5 reach 6 -0.3 1.2\n"
      "path 0 0\n"
      "curve 1 0 2 0 3 0 speed 1.4\n"
      "curve 4 0 5 0 6 0 gap\n",
      "s.txt");
  EXPECT_DOUBLE_EQ(s.fps, 25);
  EXPECT_DOUBLE_EQ(s.duration, 4.5);
  EXPECT_EQ(s.start_space, "locomotion");
  EXPECT_DOUBLE_EQ(s.start_p, 1.2);
  EXPECT_DOUBLE_EQ(s.start_t, 0.3);
  ASSERT_EQ(s.events.size(), 6u);
  EXPECT_EQ(s.events[5].command, ScriptCommand::kReach);
  EXPECT_DOUBLE_EQ(s.events[5].b, -0.3);
  EXPECT_DOUBLE_EQ(s.events[5].c, 1.2);
  EXPECT_EQ(s.events[0].command, ScriptCommand::kParam);  // sorted by time
  EXPECT_EQ(s.events[1].command, ScriptCommand::kMotion);
  EXPECT_EQ(s.events[1].space, "jump_length");
  EXPECT_DOUBLE_EQ(s.events[1].b, 0.4);
  EXPECT_EQ(s.events[1].line, 5);
  ASSERT_EQ(s.path.size(), 2u);
  EXPECT_DOUBLE_EQ(s.path[0].speed, 1.4);
  EXPECT_TRUE(s.path[1].gap);
  EXPECT_DOUBLE_EQ(s.path[1].control[0].x, 3);
}

TEST(ControlScript, MalformedLinesNameTheLineAndTheReason) {
  EXPECT_NE(parse_error("start locomotion 1\nat x param 1\n").find("s.txt:2: a time in seconds 'x' is not a number"),
            std::string::npos);
  EXPECT_NE(parse_error("start locomotion\nat 1 dance 2\n").find("s.txt:2: unknown command 'dance'"),
            std::string::npos);
  EXPECT_NE(parse_error("start locomotion\n\n\nat 1 param\n").find("s.txt:4:"), std::string::npos);
  EXPECT_NE(parse_error("start locomotion\nfps 30 60\n").find("s.txt:2:"), std::string::npos);
  EXPECT_NE(parse_error("start locomotion\ncurve 1 0 2 0 3 0\n").find("s.txt:2: 'curve' before 'path'"),
            std::string::npos);
  EXPECT_NE(parse_error("start locomotion\npath 0 0\ncurve 1 0 2 0 3\n").find("s.txt:3:"),
            std::string::npos);
  EXPECT_NE(parse_error("at 1 param 1\n").find("no 'start"), std::string::npos);
  EXPECT_NE(parse_error("start locomotion\nat -1 param 1\n").find("s.txt:2:"), std::string::npos);
  EXPECT_NE(parse_error("start locomotion 1 2\n").find("s.txt:1: start time"), std::string::npos);
  EXPECT_NE(parse_error("start locomotion\nat 1 reach 2 0\n")
                .find("s.txt:2: 'reach' needs a target x y z"),
            std::string::npos);
  EXPECT_EQ(parse_error("start locomotion\n"), "");
  // An unknown space is caught against the asset, with its line.
  const ControlScript s = parse_control_script("start locomotion\nat 1 motion swim 1\n", "s.txt");
  const MotionGraph g = test::make_test_graph(false);
  try {
    check_control_script(s, g);
    FAIL() << "unknown space accepted";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("s.txt:2: unknown motion space 'swim'"), std::string::npos);
  }
}

TEST(Player, WritesMeshesAndLogs) {
  const Asset asset = load_asset(test_asset());
  const ControlScript script = parse_control_script(
      "fps 20\nduration 3\nstart locomotion 1.2\nat 0.5 param 9\nat 1.0 motion jump_length 1.0\n"
      "at 2.5 motion turning 10\n",
      "timeline.txt");
  PlayerOptions o;
  o.out_dir = test::scratch_dir("out");
  o.mesh_every = 10;
  const PlayerReport r = run_player(asset, script, o);
  EXPECT_EQ(r.frames, 61);
  EXPECT_EQ(r.meshes, 7);
  EXPECT_EQ(r.clamped, 1);
  EXPECT_GE(r.transitions, 1);
  EXPECT_TRUE(fs::exists(o.out_dir / "meshes" / "frame_00060.ply"));
  std::ifstream csv(o.out_dir / "frames.csv");
  std::string line;
  int lines = 0;
  bool switched = false;
  while (std::getline(csv, line)) {
    ++lines;
    switched |= line.find("switch locomotion -> jump_length") != std::string::npos;
  }
  EXPECT_EQ(lines, 62);
  EXPECT_TRUE(switched);
  std::ifstream jl(o.out_dir / "transitions.jsonl");
  ASSERT_TRUE(std::getline(jl, line));
  const nlohmann::json t = nlohmann::json::parse(line);
  EXPECT_EQ(t["from"], "locomotion");
  EXPECT_EQ(t["to"], "jump_length");
  EXPECT_GE(t["latency_s"].get<double>(), 0.0);
  EXPECT_GE(t["switch_time_s"].get<double>(), 1.0);
  // The transition's worst vertex step, against the motions' own.
  EXPECT_GT(t["max_vertex_step_mm"].get<double>(), 0.0);
  EXPECT_GT(t["source_step_p99_mm"].get<double>(), 0.0);
  EXPECT_NEAR(t["jump_ratio"].get<double>(),
              t["max_vertex_step_mm"].get<double>() /
                  std::max(t["source_step_p99_mm"].get<double>(), t["target_step_p99_mm"].get<double>()),
              1e-9);
  EXPECT_LE(t["jump_ratio"].get<double>(), 1.5);
  const nlohmann::json summary = nlohmann::json::parse(read_file(o.out_dir / "summary.json"));
  EXPECT_EQ(summary["frames"], 61);
}

TEST(Player, SameScriptAt30And60HzGivesTheSameStates) {
  const Asset asset = load_asset(test_asset());
  const std::string text =
      "duration 4\nstart locomotion 1.1\nat 0.7 param 1.5\nat 1.3 motion jump_length 0.8\n"
      "at 2.9 turn 15\n";
  auto rows = [&](double fps, const std::string& name) {
    PlayerOptions o;
    o.out_dir = test::scratch_dir(name);
    o.fps = fps;
    o.write_meshes = false;
    run_player(asset, parse_control_script(text, "t.txt"), o);
    std::ifstream csv(o.out_dir / "frames.csv");
    std::vector<std::string> out;
    std::string line;
    std::getline(csv, line);
    while (std::getline(csv, line)) {
      // time .. heading (columns 2-12), without the frame number and the event columns.
      std::stringstream ss(line);
      std::string cell, kept;
      for (int c = 0; std::getline(ss, cell, ','); ++c) {
        if (c >= 1 && c <= 11 && c != 6) kept += cell + ",";
      }
      out.push_back(kept);
    }
    return out;
  };
  const std::vector<std::string> a = rows(30, "r30"), b = rows(60, "r60");
  ASSERT_EQ(b.size(), 2 * a.size() - 1);
  for (std::size_t k = 0; k < a.size(); ++k) EXPECT_EQ(a[k], b[2 * k]) << "frame " << k;
}

int run_play(const std::string& args, std::string* output) {
  const fs::path bin = fs::path(FOURD_BIN_DIR) / "fourd-play";
  const fs::path log = test::scratch_dir("cli") / "out.txt";
  const int status = std::system((bin.string() + " " + args + " >" + log.string() + " 2>&1").c_str());
  *output = read_file(log);
  return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

TEST(PlayerExecutable, RefusesBadInputWithAClearMessage) {
  const fs::path bin = fs::path(FOURD_BIN_DIR) / "fourd-play";
  if (!fs::exists(bin)) GTEST_SKIP() << "fourd-play not built";
  const fs::path d = test::scratch_dir("bad");
  write_file_atomic(d / "good.txt", "duration 0.2\nstart locomotion 1.2\n");
  write_file_atomic(d / "bad.txt", "start locomotion 1.2\nat 0.1 motion jump_length\n");
  std::string out;
  // A good run.
  EXPECT_EQ(run_play(test_asset().string() + " " + (d / "good.txt").string() + " -o " +
                         (d / "good").string(),
                     &out),
            0)
      << out;
  EXPECT_TRUE(fs::exists(d / "good" / "frames.csv"));
  // A malformed script: the line and the reason.
  EXPECT_EQ(run_play(test_asset().string() + " " + (d / "bad.txt").string() + " -o " +
                         (d / "o1").string(),
                     &out),
            kExitInput);
  EXPECT_NE(out.find("bad.txt:2:"), std::string::npos) << out;
  EXPECT_NE(out.find("a parameter value"), std::string::npos) << out;
  // A truncated asset.
  const std::string bytes = read_file(test_asset());
  write_file_atomic(d / "truncated.fourd", std::string_view(bytes).substr(0, bytes.size() / 2));
  EXPECT_EQ(run_play((d / "truncated.fourd").string() + " " + (d / "good.txt").string() + " -o " +
                         (d / "o2").string(),
                     &out),
            kExitInput);
  EXPECT_NE(out.find("truncated.fourd"), std::string::npos) << out;
  // A flipped bit, another format version, the other byte order: refused, named, exit 4.
  std::string flipped = bytes;
  flipped[bytes.size() / 3] ^= 0x10;
  std::string old_version = bytes;  // version 1: older than the oldest the runtime reads (2)
  old_version[8] = 1;
  std::string swapped = bytes;
  std::reverse(swapped.begin() + 12, swapped.begin() + 16);
  for (const auto& [name, content, reason] :
       {std::tuple<std::string, std::string, std::string>{"flipped", flipped, "checksum"},
        {"old_version", old_version, "not supported"},
        {"swapped", swapped, "endianness"}}) {
    write_file_atomic(d / (name + ".fourd"), content);
    EXPECT_EQ(run_play((d / (name + ".fourd")).string() + " " + (d / "good.txt").string() +
                           " -o " + (d / name).string(),
                       &out),
              kExitInput)
        << out;
    EXPECT_NE(out.find(name + ".fourd"), std::string::npos) << out;
    EXPECT_NE(out.find(reason), std::string::npos) << out;
    EXPECT_FALSE(fs::exists(d / name / "frames.csv"));
  }
  // Not an asset at all.
  write_file_atomic(d / "junk.fourd", "hello");
  EXPECT_NE(run_play((d / "junk.fourd").string() + " " + (d / "good.txt").string() + " -o " +
                         (d / "o3").string(),
                     &out),
            0);
  EXPECT_NE(out.find("junk.fourd"), std::string::npos) << out;
  // A missing asset.
  EXPECT_EQ(run_play((d / "missing.fourd").string() + " " + (d / "good.txt").string() + " -o " +
                         (d / "o4").string(),
                     &out),
            kExitIo);
}

}  // namespace
}  // namespace fourd
