#include "stages/synth/bvh_io.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <numbers>
#include <random>
#include <set>

#include "pipeline/core/error.h"
#include "stages/synth/body_model.h"

namespace fourd::synth {
namespace {

namespace fs = std::filesystem;

fs::path temp_dir(const std::string& name) {
  const fs::path dir = fs::temp_directory_path() / ("fourd_bvh_io_test_" + name);
  fs::remove_all(dir);
  fs::create_directories(dir);
  return dir;
}

// A small biped: pelvis, spine, chest, neck, head, left arm chain, both legs (not in
// depth-first order, to check the writer nests the hierarchy by parents).
Skeleton make_test_skeleton() {
  Skeleton s;
  auto add = [&](const std::string& name, int parent, Eigen::Vector3d offset) {
    s.names.push_back(name);
    s.parents.push_back(parent);
    s.rest_offsets.push_back(offset);
  };
  add("pelvis", -1, {0.01, 0.0, 0.95});
  add("spine", 0, {0, 0, 0.12});
  add("thigh_l", 0, {0, 0.09, -0.05});
  add("thigh_r", 0, {0, -0.09, -0.05});
  add("chest", 1, {0, 0, 0.2});
  add("shin_l", 2, {0, 0, -0.42});
  add("shin_r", 3, {0, 0, -0.42});
  add("neck", 4, {0, 0, 0.18});
  add("upper_arm_l", 4, {0, 0.18, 0.12});
  add("foot_l", 5, {0, 0, -0.4});
  add("foot_r", 6, {0, 0, -0.4});
  add("head", 7, {0, 0, 0.1});
  add("forearm_l", 8, {0, 0.2, -0.2});
  add("hand_l", 12, {0, 0.18, -0.18});
  return s;
}

std::vector<Pose> make_test_poses(const Skeleton& s, int frames, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(-1, 1);
  std::vector<Pose> poses;
  for (int f = 0; f < frames; ++f) {
    Pose pose;
    pose.root_position = {0.4 * f, 0.1 * u(rng), 0.9 + 0.05 * u(rng)};
    for (std::size_t j = 0; j < s.size(); ++j) {
      const Eigen::Vector3d axis = Eigen::Vector3d(u(rng), u(rng), u(rng)).normalized();
      pose.local_rotations.emplace_back(Eigen::AngleAxisd(2.5 * u(rng), axis));
    }
    poses.push_back(pose);
  }
  // Gimbal lock of the written Z-X-Y order: exactly +-90 degrees about BVH x (our +y), after a
  // turn about BVH z (our +x).
  poses[0].local_rotations[4] = Eigen::AngleAxisd(0.7, Eigen::Vector3d::UnitX()) *
                                Eigen::AngleAxisd(std::numbers::pi / 2, Eigen::Vector3d::UnitY());
  poses[1].local_rotations[2] = Eigen::AngleAxisd(-std::numbers::pi / 2, Eigen::Vector3d::UnitY());
  return poses;
}

// Largest distance between joints of the same name in two posed skeletons.
double max_joint_error(const Skeleton& a, const Pose& pa, const Skeleton& b, const Pose& pb) {
  const auto wa = forward_kinematics(a, pa);
  const auto wb = forward_kinematics(b, pb);
  double worst = 0;
  for (std::size_t j = 0; j < a.size(); ++j) {
    const int k = b.find(a.names[j]);
    EXPECT_GE(k, 0) << a.names[j];
    if (k < 0) continue;
    worst = std::max(worst, (wa[j].translation() - wb[k].translation()).norm());
  }
  return worst;
}

TEST(BvhIo, WrittenFileDrivesTheSkeletonAsWritten) {
  const fs::path dir = temp_dir("roundtrip");
  const Skeleton skeleton = make_test_skeleton();
  const std::vector<Pose> poses = make_test_poses(skeleton, 20, 1);
  write_bvh(dir / "take.bvh", skeleton, poses, 30);
  const BvhMotion motion = read_bvh(dir / "take.bvh");

  ASSERT_EQ(motion.skeleton.size(), skeleton.size());
  ASSERT_EQ(motion.frames.size(), poses.size());
  EXPECT_NEAR(motion.frame_time, 1.0 / 30, 1e-9);
  EXPECT_EQ(motion.skeleton.names[0], "pelvis");
  EXPECT_EQ(motion.channels[0].size(), 6u);
  EXPECT_EQ(motion.channels[1], (std::vector<std::string>{"Zrotation", "Xrotation", "Yrotation"}));
  // Leaves end in End Sites: head, hand_l, foot_l, foot_r.
  EXPECT_EQ(motion.end_sites.size(), 4u);
  for (std::size_t f = 0; f < poses.size(); ++f)
    EXPECT_LT(max_joint_error(skeleton, poses[f], motion.skeleton, motion.frames[f]), 1e-4)
        << "frame " << f;
}

// A hand-written file in the usual y-up, centimetre convention with another rotation order:
// the joint channels compose in the order listed and the axes turn to ours.
TEST(BvhIo, ReadsEulerOrdersAndAxesAsWritten) {
  const fs::path dir = temp_dir("orders");
  std::ofstream(dir / "xyz.bvh") << R"(HIERARCHY
ROOT Hips
{
  OFFSET 0 0 0
  CHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation Yrotation
  JOINT Chest
  {
    OFFSET 0 10 0
    CHANNELS 3 Xrotation Yrotation Zrotation
    JOINT Head
    {
      OFFSET 0 0 10
      CHANNELS 3 Xrotation Yrotation Zrotation
      End Site
      {
        OFFSET 0 5 0
      }
    }
  }
}
MOTION
Frames: 3
Frame Time: 0.04
0 100 0 0 0 0 0 0 0 0 0 0
0 100 0 0 0 0 90 90 0 0 0 0
0 100 0 0 0 90 0 0 0 0 0 0
)";
  const BvhMotion motion = read_bvh(dir / "xyz.bvh");
  ASSERT_EQ(motion.frames.size(), 3u);
  EXPECT_DOUBLE_EQ(motion.fps(), 25);
  // A vector, not Eigen's expression: that would refer into the temporary poses.
  auto head = [&](int f) -> Eigen::Vector3d {
    return forward_kinematics(motion.skeleton, motion.frames[f])[2].translation();
  };
  // Rest: root 1 m up, chest 10 cm above, head 10 cm in front (BVH +z = our +x).
  EXPECT_LT((head(0) - Eigen::Vector3d(0.1, 0, 1.1)).norm(), 1e-12);
  // Rx(90) * Ry(90) turns the BVH +z offset onto BVH +x = our +y (the other order would give
  // BVH -y = our -z).
  EXPECT_LT((head(1) - Eigen::Vector3d(0, 0.1, 1.1)).norm(), 1e-12);
  // Root yaw of 90 degrees about BVH +y (up) turns our +x onto our +y, counter-clockwise.
  EXPECT_LT((head(2) - Eigen::Vector3d(0, 0.1, 1.1)).norm(), 1e-12);
  ASSERT_EQ(motion.end_sites.size(), 1u);
  EXPECT_EQ(motion.end_sites[0].first, 2);
  EXPECT_LT((motion.end_sites[0].second - Eigen::Vector3d(0, 0, 0.05)).norm(), 1e-12);
}

std::string read_error(const fs::path& path) {
  try {
    read_bvh(path);
  } catch (const InputError& e) {
    return e.what();
  }
  return "";
}

TEST(BvhIo, MalformedFilesGiveErrorsNamingFileAndLine) {
  const fs::path dir = temp_dir("malformed");
  const std::string header = R"(HIERARCHY
ROOT Hips
{
  OFFSET 0 0 0
  CHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation Yrotation
  End Site
  {
    OFFSET 0 10 0
  }
}
MOTION
Frames: 2
Frame Time: 0.04
)";
  std::ofstream(dir / "short_line.bvh") << header << "0 0 0 0 0 0\n0 0 0 0 0\n";
  std::string error = read_error(dir / "short_line.bvh");
  EXPECT_NE(error.find("short_line.bvh:15:"), std::string::npos) << error;
  EXPECT_NE(error.find("5 values"), std::string::npos) << error;

  std::ofstream(dir / "truncated.bvh") << header << "0 0 0 0 0 0\n";
  error = read_error(dir / "truncated.bvh");
  EXPECT_NE(error.find("truncated.bvh:"), std::string::npos) << error;
  EXPECT_NE(error.find("1 of the 2 frames"), std::string::npos) << error;

  std::ofstream(dir / "bad_number.bvh") << header << "0 0 0 0 0 0\n0 0 x 0 0 0\n";
  error = read_error(dir / "bad_number.bvh");
  EXPECT_NE(error.find("bad_number.bvh:15:"), std::string::npos) << error;
  EXPECT_NE(error.find("'x'"), std::string::npos) << error;

  std::string channel = header;
  channel.replace(channel.find("Yrotation"), 9, "Wrotation");
  std::ofstream(dir / "bad_channel.bvh") << channel << "0 0 0 0 0 0\n0 0 0 0 0 0\n";
  error = read_error(dir / "bad_channel.bvh");
  EXPECT_NE(error.find("bad_channel.bvh:5:"), std::string::npos) << error;
  EXPECT_NE(error.find("Wrotation"), std::string::npos) << error;

  std::string brace = header;
  brace.erase(brace.find("  {\n    OFFSET 0 10 0"), 4);
  std::ofstream(dir / "no_brace.bvh") << brace;
  error = read_error(dir / "no_brace.bvh");
  EXPECT_NE(error.find("no_brace.bvh:7:"), std::string::npos) << error;
  EXPECT_NE(error.find("expected '{'"), std::string::npos) << error;

  EXPECT_THROW(read_bvh(dir / "missing.bvh"), IoError);
}

TEST(BvhIo, RetargetingOntoTheSameSkeletonReproducesJointPositions) {
  const fs::path dir = temp_dir("retarget_self");
  const Skeleton skeleton = make_test_skeleton();
  const std::vector<Pose> poses = make_test_poses(skeleton, 15, 2);
  write_bvh(dir / "take.bvh", skeleton, poses, 25);
  const BvhMotion motion = read_bvh(dir / "take.bvh");
  std::map<std::string, std::string> identity;
  for (const std::string& name : skeleton.names) identity[name] = name;
  const std::vector<Pose> retargeted = retarget_bvh(motion, skeleton, identity);
  ASSERT_EQ(retargeted.size(), poses.size());
  for (std::size_t f = 0; f < poses.size(); ++f)
    EXPECT_LT(max_joint_error(skeleton, poses[f], skeleton, retargeted[f]), 1e-4) << "frame " << f;
}

// A target with longer bones and the arm resting 40 degrees lower (an A-pose against the
// source's pose): mapped bones point where the source's bones point, the root travels scaled by
// the leg-length ratio, and an unmapped joint follows its parent.
TEST(BvhIo, RetargetingCompensatesProportionsAndRestPose) {
  BvhMotion motion;
  motion.source = "in-memory";
  motion.skeleton = make_test_skeleton();
  motion.frames = make_test_poses(motion.skeleton, 10, 3);
  motion.frame_time = 0.04;
  // Give the source Mixamo-style names to exercise the default map.
  const std::map<std::string, std::string> mixamo = {{"pelvis", "mixamorig:Hips"},
                                                     {"spine", "mixamorig:Spine"},
                                                     {"chest", "mixamorig:Spine2"},
                                                     {"neck", "mixamorig:Neck"},
                                                     {"head", "mixamorig:Head"},
                                                     {"upper_arm_l", "mixamorig:LeftArm"},
                                                     {"forearm_l", "mixamorig:LeftForeArm"},
                                                     {"hand_l", "mixamorig:LeftHand"},
                                                     {"thigh_l", "mixamorig:LeftUpLeg"},
                                                     {"shin_l", "mixamorig:LeftLeg"},
                                                     {"foot_l", "mixamorig:LeftFoot"},
                                                     {"thigh_r", "mixamorig:RightUpLeg"},
                                                     {"shin_r", "mixamorig:RightLeg"},
                                                     {"foot_r", "mixamorig:RightFoot"}};
  for (std::string& name : motion.skeleton.names) name = mixamo.at(name);

  Skeleton target = make_test_skeleton();
  for (Eigen::Vector3d& o : target.rest_offsets) o *= 1.3;
  target.rest_offsets[0].z() = 0.95 * 1.3;
  const Eigen::AngleAxisd lower(-0.7, Eigen::Vector3d::UnitX());  // arm towards the body
  for (const char* j : {"forearm_l", "hand_l"})
    target.rest_offsets[target.find(j)] = lower * target.rest_offsets[target.find(j)];
  // An extra joint the source does not have.
  target.names.push_back("toe_l");
  target.parents.push_back(target.find("foot_l"));
  target.rest_offsets.push_back({0.15, 0, -0.05});

  const std::vector<Pose> out = retarget_bvh(motion, target);
  ASSERT_EQ(out.size(), motion.frames.size());
  const std::vector<std::pair<std::string, std::string>> bones = {
      {"upper_arm_l", "forearm_l"}, {"forearm_l", "hand_l"}, {"thigh_l", "shin_l"},
      {"shin_r", "foot_r"},         {"chest", "neck"},       {"neck", "head"}};
  for (std::size_t f = 0; f < out.size(); ++f) {
    const auto src = forward_kinematics(motion.skeleton, motion.frames[f]);
    const auto dst = forward_kinematics(target, out[f]);
    const Skeleton& s = motion.skeleton;
    for (const auto& [a, b] : bones) {
      const Eigen::Vector3d ds =
          (src[s.find(mixamo.at(b))].translation() - src[s.find(mixamo.at(a))].translation())
              .normalized();
      const Eigen::Vector3d dt =
          (dst[target.find(b)].translation() - dst[target.find(a)].translation()).normalized();
      EXPECT_LT((ds - dt).norm(), 1e-9) << a << " -> " << b << " frame " << f;
    }
    EXPECT_LT((out[f].root_position - 1.3 * motion.frames[f].root_position).norm(), 1e-9);
    const int toe = target.find("toe_l"), foot = target.find("foot_l");
    EXPECT_LT((dst[toe].linear() - dst[foot].linear()).norm(), 1e-9);
  }
}

TEST(BvhIo, RetargetingWithoutARootMappingIsAnError) {
  BvhMotion motion;
  motion.source = "take.bvh";
  motion.skeleton = make_test_skeleton();
  motion.frames = make_test_poses(motion.skeleton, 2, 4);
  try {
    retarget_bvh(motion, make_test_skeleton(), {{"spine", "spine"}});
    FAIL() << "a map without the root was accepted";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("take.bvh"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("pelvis"), std::string::npos) << e.what();
  }
}

// Motion capture with Mixamo names drives the procedural performer's skeleton through the
// default map: every one of its joints is mapped, so the motion is reproduced exactly.
TEST(BvhIo, DefaultMapRetargetsMixamoNamesOntoTheProceduralSkeleton) {
  const fs::path dir = temp_dir("mixamo");
  const Skeleton performer = detail::make_body_model(1.75, 1.0).skeleton;
  const std::map<std::string, std::string> mixamo_name = {{"pelvis", "Hips"},
                                                          {"spine", "Spine"},
                                                          {"chest", "Spine2"},
                                                          {"neck", "Neck"},
                                                          {"head", "Head"},
                                                          {"clavicle_l", "LeftShoulder"},
                                                          {"upper_arm_l", "LeftArm"},
                                                          {"forearm_l", "LeftForeArm"},
                                                          {"hand_l", "LeftHand"},
                                                          {"clavicle_r", "RightShoulder"},
                                                          {"upper_arm_r", "RightArm"},
                                                          {"forearm_r", "RightForeArm"},
                                                          {"hand_r", "RightHand"},
                                                          {"thigh_l", "LeftUpLeg"},
                                                          {"shin_l", "LeftLeg"},
                                                          {"foot_l", "LeftFoot"},
                                                          {"toe_l", "LeftToeBase"},
                                                          {"thigh_r", "RightUpLeg"},
                                                          {"shin_r", "RightLeg"},
                                                          {"foot_r", "RightFoot"},
                                                          {"toe_r", "RightToeBase"}};
  Skeleton mocap = performer;
  for (std::string& name : mocap.names) {
    ASSERT_TRUE(mixamo_name.count(name)) << "procedural joint '" << name << "' has no mocap name";
    name = "mixamorig:" + mixamo_name.at(name);
  }
  const std::vector<Pose> poses = make_test_poses(performer, 8, 5);
  write_bvh(dir / "mixamo.bvh", mocap, poses, 30);
  const std::vector<Pose> out = retarget_bvh(read_bvh(dir / "mixamo.bvh"), performer);
  ASSERT_EQ(out.size(), poses.size());
  for (std::size_t f = 0; f < poses.size(); ++f)
    EXPECT_LT(max_joint_error(performer, poses[f], performer, out[f]), 1e-4) << "frame " << f;
}

TEST(BvhIo, DefaultMapCoversTheProceduralSkeletonNames) {
  const auto map = default_bvh_joint_map();
  std::set<std::string> targets;
  for (const auto& [source, target] : map) targets.insert(target);
  for (const char* name :
       {"pelvis",     "spine",       "chest",       "neck",      "head",      "clavicle_l",
        "clavicle_r", "upper_arm_l", "upper_arm_r", "forearm_l", "forearm_r", "hand_l",
        "hand_r",     "thigh_l",     "thigh_r",     "shin_l",    "shin_r",    "foot_l",
        "foot_r",     "toe_l",       "toe_r"})
    EXPECT_TRUE(targets.count(name)) << name;
  EXPECT_EQ(map.at("LeftUpLeg"), "thigh_l");
  EXPECT_EQ(map.at("RightForeArm"), "forearm_r");
  EXPECT_EQ(map.at("Hips"), "pelvis");
}

}  // namespace
}  // namespace fourd::synth
