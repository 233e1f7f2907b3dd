#include "pipeline/core/config.h"

#include <gtest/gtest.h>

namespace fourd {
namespace {

struct Inner {
  int count = 8;
  double radius = 3.0;
  template <class V>
  void visit(V& v) {
    v("count", count, "cameras", Range{1, 64});
    v("radius", radius, "radius [m]", Range{0.5, 10});
  }
};

struct Outer {
  std::string name = "x";
  bool flag = false;
  Inner inner;
  std::vector<Inner> list;
  std::vector<double> values;
  template <class V>
  void visit(V& v) {
    v("name", name, "name");
    v("flag", flag, "flag");
    v("inner", inner, "inner options");
    v("list", list, "list of inner");
    v("values", values, "numbers");
  }
  void check() const {
    if (name == "bad") throw ConfigError("name must not be 'bad'");
  }
};

Outer parse(const std::string& text) {
  Outer o;
  read_options("test.yaml", YAML::Load(text), "", o);
  return o;
}

std::string error_of(const std::string& text) {
  try {
    parse(text);
  } catch (const ConfigError& e) {
    return e.what();
  }
  return "";
}

TEST(Config, ReadsNestedValuesAndKeepsDefaults) {
  Outer o = parse("name: y\ninner: {count: 3}\nlist: [{radius: 2}, {count: 5}]\nvalues: [1, 2.5]\n");
  EXPECT_EQ(o.name, "y");
  EXPECT_FALSE(o.flag);
  EXPECT_EQ(o.inner.count, 3);
  EXPECT_DOUBLE_EQ(o.inner.radius, 3.0);
  ASSERT_EQ(o.list.size(), 2u);
  EXPECT_DOUBLE_EQ(o.list[0].radius, 2.0);
  EXPECT_EQ(o.list[1].count, 5);
  EXPECT_EQ(o.values, (std::vector<double>{1, 2.5}));
}

TEST(Config, UnknownKeyNamesFileLineAndPath) {
  std::string e = error_of("name: y\ninner:\n  cout: 3\n");
  EXPECT_NE(e.find("test.yaml:3"), std::string::npos) << e;
  EXPECT_NE(e.find("inner.cout"), std::string::npos) << e;
  EXPECT_NE(e.find("known keys: count, radius"), std::string::npos) << e;
}

TEST(Config, OutOfRangeAndWrongType) {
  std::string e = error_of("inner: {count: 0}\n");
  EXPECT_NE(e.find("inner.count"), std::string::npos) << e;
  EXPECT_NE(e.find("out of range [1, 64]"), std::string::npos) << e;
  e = error_of("inner: {radius: far}\n");
  EXPECT_NE(e.find("'far' is not a number"), std::string::npos) << e;
  e = error_of("list: [{count: 100}]\n");
  EXPECT_NE(e.find("list[0].count"), std::string::npos) << e;
}

TEST(Config, CheckIsCalled) {
  EXPECT_NE(error_of("name: bad\n").find("must not be 'bad'"), std::string::npos);
}

TEST(Config, WriteThenReadRoundTrips) {
  Outer o = parse("name: z\nflag: true\ninner: {count: 7, radius: 1.5}\nlist: [{count: 2}]\n");
  YAML::Node written = to_yaml(o);
  Outer back;
  read_options("mem", YAML::Load(YAML::Dump(written)), "", back);
  EXPECT_EQ(back.name, "z");
  EXPECT_TRUE(back.flag);
  EXPECT_EQ(back.inner.count, 7);
  EXPECT_DOUBLE_EQ(back.inner.radius, 1.5);
  ASSERT_EQ(back.list.size(), 1u);
  EXPECT_EQ(back.list[0].count, 2);
}

TEST(Config, DescribeListsEveryFieldWithItsDefault) {
  Outer o;
  o.values = {0.1, 2.5};
  o.inner.radius = 0.1;
  const std::string text = describe_options(o);
  EXPECT_NE(text.find("name = x: name\n"), std::string::npos) << text;
  EXPECT_NE(text.find("flag = false: flag\n"), std::string::npos) << text;
  EXPECT_NE(text.find("inner: inner options\n    count = 8: cameras\n    radius = 0.1: radius [m]\n"),
            std::string::npos)
      << text;
  EXPECT_NE(text.find("list (list): list of inner\n"), std::string::npos) << text;
  EXPECT_NE(text.find("values = [0.1, 2.5]: numbers\n"), std::string::npos) << text;
}

// Subject-relative lengths: defaults for the reference subject, scaled unless set.
struct Sized {
  double voxel = 0.006;
  double tolerance = 0.01;
  int iterations = 4;
  std::vector<double> box = {-1.0, 2.0};
  template <class V>
  void visit(V& v) {
    v("voxel", voxel, "voxel [m]", Length{1e-5, 1});
    v("tolerance", tolerance, "tolerance [m]", Length{1e-6, 1});
    v("iterations", iterations, "not a length", Range{0, 100});
    v("box", box, "a box [m]", Length{});
  }
};
struct SizedOuter {
  Sized inner;
  double ratio = 0.5;
  template <class V>
  void visit(V& v) {
    v("inner", inner, "inner");
    v("ratio", ratio, "a ratio", Range{0, 1});
  }
  void check() const {
    if (inner.tolerance > 10 * inner.voxel) throw ConfigError("tolerance above 10 voxels");
  }
};

TEST(Config, ScalesOnlyTheLengthsNotSet) {
  SizedOuter o;
  SetKeys set;
  read_options("session.yaml", YAML::Load("inner: {tolerance: 0.02, iterations: 7}\n"),
               "stages.x", o, &set);
  EXPECT_TRUE(set.count("stages.x.inner.tolerance"));
  EXPECT_FALSE(set.count("stages.x.inner.voxel"));
  const std::vector<std::string> scaled = scale_unset_lengths(o, 2.0, set, "stages.x");
  EXPECT_DOUBLE_EQ(o.inner.voxel, 0.012);       // default, scaled
  EXPECT_DOUBLE_EQ(o.inner.tolerance, 0.02);    // set: kept
  EXPECT_EQ(o.inner.iterations, 7);             // not a length
  EXPECT_DOUBLE_EQ(o.ratio, 0.5);
  EXPECT_EQ(o.inner.box, (std::vector<double>{-2.0, 4.0}));
  EXPECT_EQ(scaled, (std::vector<std::string>{"stages.x.inner.voxel", "stages.x.inner.box"}));
  // The options used show the derived value.
  const YAML::Node used = to_yaml(o);
  EXPECT_DOUBLE_EQ(used["inner"]["voxel"].as<double>(), 0.012);
  EXPECT_DOUBLE_EQ(used["inner"]["tolerance"].as<double>(), 0.02);
}

TEST(Config, KeysSetByAnyLayerAreKeptAndFactorOneChangesNothing) {
  SizedOuter o;
  SetKeys set;
  read_options("preset.yaml", YAML::Load("inner: {voxel: 0.004}\n"), "stages.x", o, &set);
  read_options("session.yaml", YAML::Load("ratio: 0.25\n"), "stages.x", o, &set);
  SizedOuter same = o;
  scale_unset_lengths(same, 1.0, set, "stages.x");
  EXPECT_EQ(YAML::Dump(to_yaml(same)), YAML::Dump(to_yaml(o)));
  scale_unset_lengths(o, 0.05, set, "stages.x");
  EXPECT_DOUBLE_EQ(o.inner.voxel, 0.004);
  EXPECT_DOUBLE_EQ(o.inner.tolerance, 0.01 * 0.05);
}

TEST(Config, ScalingChecksTheOptionsAgain) {
  // An explicit voxel with a scaled-up tolerance breaks the cross-field check.
  SizedOuter o;
  SetKeys set;
  read_options("session.yaml", YAML::Load("inner: {voxel: 0.002}\n"), "stages.x", o, &set);
  EXPECT_THROW(scale_unset_lengths(o, 3.0, set, "stages.x"), ConfigError);
}

// Tuned lengths that are not options: scaled like the options' lengths, never read, written
// or described.
struct Tuned {
  double margin = 0.03;
  template <class V>
  void internal_lengths(V& v) {
    v("margin", margin, "", Length{0, 1});
  }
};
struct WithTuned {
  double voxel = 0.006;
  double band = 0.12;  // tuned, not an option
  Tuned tuned;         // tuned, not an option
  Sized sized;
  template <class V>
  void visit(V& v) {
    v("voxel", voxel, "voxel [m]", Length{1e-5, 1});
    v("sized", sized, "sized");
  }
  template <class V>
  void internal_lengths(V& v) {
    v("band", band, "", Length{0, 2});
    v("tuned", tuned, "");
  }
};

TEST(Config, ScalesTunedLengthsThatAreNotOptions) {
  WithTuned o;
  SetKeys set;
  read_options("session.yaml", YAML::Load("voxel: 0.004\n"), "stages.x", o, &set);
  const std::vector<std::string> scaled = scale_unset_lengths(o, 2.0, set, "stages.x");
  EXPECT_DOUBLE_EQ(o.voxel, 0.004);  // set: kept
  EXPECT_DOUBLE_EQ(o.band, 0.24);
  EXPECT_DOUBLE_EQ(o.tuned.margin, 0.06);
  EXPECT_DOUBLE_EQ(o.sized.voxel, 0.012);
  EXPECT_EQ(scaled, (std::vector<std::string>{"stages.x.sized.voxel", "stages.x.sized.tolerance",
                                              "stages.x.sized.box", "stages.x.band",
                                              "stages.x.tuned.margin"}));
  EXPECT_FALSE(to_yaml(o)["band"].IsDefined());
  EXPECT_EQ(describe_options(o).find("band"), std::string::npos);
  try {
    read_options("session.yaml", YAML::Load("band: 0.1\n"), "stages.x", o);
    FAIL() << "a tuned value is not an option";
  } catch (const ConfigError& e) {
    EXPECT_NE(std::string(e.what()).find("unknown key 'band'"), std::string::npos) << e.what();
  }
}

TEST(Config, DescribeMarksSubjectLengths) {
  const std::string text = describe_options(SizedOuter{});
  EXPECT_NE(text.find("voxel = 0.006 (scaled to the subject): voxel [m]"), std::string::npos);
  EXPECT_NE(text.find("iterations = 4: not a length"), std::string::npos);
}

}  // namespace
}  // namespace fourd
