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

// The q-quantile of `v` (0 <= q <= 1), nearest rank; 0 when empty.
inline double percentile(std::vector<double> v, double q) {
  if (v.empty()) return 0;
  const std::size_t k =
      std::min(v.size() - 1, static_cast<std::size_t>(q * (v.size() - 1) + 0.5));
  std::nth_element(v.begin(), v.begin() + k, v.end());
  return v[k];
}

}  // namespace fourd
