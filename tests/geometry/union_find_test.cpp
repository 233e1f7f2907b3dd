#include "pipeline/geometry/union_find.h"

#include <gtest/gtest.h>

namespace fourd {
namespace {

TEST(UnionFind, JoinedSetsShareTheirSmallestElementAsRepresentative) {
  UnionFind sets(6);
  EXPECT_EQ(sets.size(), 6u);
  for (int i = 0; i < 6; ++i) EXPECT_EQ(sets.find(i), i);
  EXPECT_TRUE(sets.unite(4, 2));
  EXPECT_TRUE(sets.unite(2, 5));
  EXPECT_TRUE(sets.unite(1, 0));
  EXPECT_EQ(sets.find(5), 2);
  EXPECT_EQ(sets.find(4), 2);
  EXPECT_EQ(sets.find(1), 0);
  EXPECT_EQ(sets.find(3), 3);
  EXPECT_FALSE(sets.unite(5, 4));  // one set already
  EXPECT_TRUE(sets.unite(5, 1));
  for (int i : {0, 1, 2, 4, 5}) EXPECT_EQ(sets.find(i), 0);
  EXPECT_EQ(sets.find(3), 3);
}

TEST(UnionFind, ALongChainIsOneSet) {
  const int n = 100000;
  UnionFind sets(n);
  for (int i = n - 1; i > 0; --i) sets.unite(i, i - 1);
  EXPECT_EQ(sets.find(n - 1), 0);
  EXPECT_EQ(sets.find(n / 2), 0);
}

}  // namespace
}  // namespace fourd
