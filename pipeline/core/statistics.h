#pragma once
// Small order statistics shared by the stages.
#include <algorithm>
#include <vector>

namespace fourd {

// The upper median of `v` (reorders it); 0 when empty.
inline double median(std::vector<double>& v) {
  if (v.empty()) return 0;
  std::nth_element(v.begin(), v.begin() + v.size() / 2, v.end());
  return v[v.size() / 2];
}

}  // namespace fourd
