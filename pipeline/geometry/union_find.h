#pragma once
// Disjoint sets of the integers 0 .. n-1 (union-find with path halving): the connected
// components of meshes. Header-only.
#include <cstddef>
#include <numeric>
#include <vector>

namespace fourd {

class UnionFind {
 public:
  explicit UnionFind(std::size_t n) : parent_(n) { std::iota(parent_.begin(), parent_.end(), 0); }

  // The representative of x's set: its smallest element.
  int find(int x) {
    while (parent_[x] != x) x = parent_[x] = parent_[parent_[x]];
    return x;
  }

  // Joins the sets of a and b; false when they were one set already.
  bool unite(int a, int b) {
    a = find(a);
    b = find(b);
    if (a == b) return false;
    if (a < b) {
      parent_[b] = a;
    } else {
      parent_[a] = b;
    }
    return true;
  }

  std::size_t size() const { return parent_.size(); }

 private:
  std::vector<int> parent_;  // #n; parent_[x] == x at a representative
};

}  // namespace fourd
