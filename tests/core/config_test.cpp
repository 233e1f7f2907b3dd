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

}  // namespace
}  // namespace fourd
