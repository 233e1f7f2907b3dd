#include "stages/timewarp/time_warp.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <optional>

#include "pipeline/core/error.h"

namespace fourd::timewarp {

namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();

// Shapes as the columns of one matrix (3 #V rows), so all pairwise distances are one product.
Eigen::MatrixXd stack(const std::vector<Eigen::Matrix3Xd>& shapes) {
  const Eigen::Index rows = shapes.empty() ? 0 : shapes[0].size();
  Eigen::MatrixXd m(rows, static_cast<Eigen::Index>(shapes.size()));
  for (std::size_t k = 0; k < shapes.size(); ++k) {
    m.col(static_cast<Eigen::Index>(k)) = shapes[k].reshaped();
  }
  return m;
}

// D(i, j) = |a_i - b_j|^2 / #V for columns a_i of `a` and b_j of `b` (3 #V rows each).
Eigen::MatrixXd pairwise_distances(const Eigen::MatrixXd& a, const Eigen::MatrixXd& b) {
  const double nv = static_cast<double>(a.rows()) / 3;
  Eigen::MatrixXd d = -2 * a.transpose() * b;
  d.colwise() += a.colwise().squaredNorm().transpose();
  d.rowwise() += b.colwise().squaredNorm();
  return d.cwiseMax(0.0) / nv;
}

// Central differences of samples taken every 1 / M of phase [per unit phase].
std::vector<Eigen::Matrix3Xd> phase_velocities(const std::vector<Eigen::Matrix3Xd>& s,
                                               bool cyclic) {
  const int count = static_cast<int>(s.size());  // M + 1; for cycles s[M] == s[0]
  const int m = count - 1;
  std::vector<Eigen::Matrix3Xd> v(count);
  for (int i = 0; i < count; ++i) {
    int prev = i - 1, next = i + 1;
    double span = 2;
    if (cyclic) {
      prev = (i - 1 + m) % m;
      next = (i + 1) % m;
    } else {
      prev = std::max(prev, 0);
      next = std::min(next, m);
      span = next - prev;
    }
    v[i] = (s[next] - s[prev]) * (m / span);
  }
  return v;
}

// Parabola through (-1, a), (0, b), (1, c): the abscissa of its vertex, within [-0.5, 0.5].
double parabola_vertex(double a, double b, double c) {
  const double curvature = a - 2 * b + c;
  if (!(curvature > 0)) return 0;
  return std::clamp(0.5 * (a - c) / curvature, -0.5, 0.5);
}

// Dynamic time warping from (0, 0) to (M, M) with local slopes between 1/2 and 2 (steps
// (1, 1), (1, 2), (2, 1)); returns, for every row i, the mean column of the path on that row.
std::vector<double> dtw_path(const Eigen::MatrixXd& d, double slope_penalty) {
  const int m = static_cast<int>(d.rows()) - 1;
  Eigen::MatrixXd cost = Eigen::MatrixXd::Constant(m + 1, m + 1, kInf);
  Eigen::MatrixXi step = Eigen::MatrixXi::Zero(m + 1, m + 1);  // 1 diagonal, 2 (1,2), 3 (2,1)
  const double off = 1 + slope_penalty;
  cost(0, 0) = d(0, 0);
  for (int i = 1; i <= m; ++i) {
    for (int j = 1; j <= m; ++j) {
      double best = cost(i - 1, j - 1) + d(i, j);
      int how = 1;
      if (j >= 2) {
        const double c = cost(i - 1, j - 2) + off * (d(i, j - 1) + d(i, j));
        if (c < best) best = c, how = 2;
      }
      if (i >= 2) {
        const double c = cost(i - 2, j - 1) + off * (d(i - 1, j) + d(i, j));
        if (c < best) best = c, how = 3;
      }
      cost(i, j) = best;
      step(i, j) = how;
    }
  }
  std::vector<double> sum(m + 1, 0.0), count(m + 1, 0.0);
  auto visit = [&](int i, int j) {
    sum[i] += j;
    count[i] += 1;
  };
  int i = m, j = m;
  visit(i, j);
  while (i > 0 || j > 0) {
    switch (step(i, j)) {
      case 2:
        visit(i, j - 1);
        i -= 1, j -= 2;
        break;
      case 3:
        visit(i - 1, j);
        i -= 2, j -= 1;
        break;
      default:
        i -= 1, j -= 1;
        break;
    }
    visit(i, j);
  }
  std::vector<double> path(m + 1);
  for (int r = 0; r <= m; ++r) path[r] = sum[r] / count[r];
  return path;
}

std::vector<Eigen::Matrix3Xd> sample_phases(const LocalTake& take, const TakeTiming& timing,
                                            double offset, int m, int count) {
  std::vector<Eigen::Matrix3Xd> s(count);
  for (int i = 0; i < count; ++i) {
    s[i] = shape_at_phase(take, timing, offset + static_cast<double>(i) / m);
  }
  return s;
}

}  // namespace

Eigen::Matrix3Xd shape_at(const LocalTake& take, double x) {
  const int n = take.num_frames();
  const double c = std::clamp(x, 0.0, n - 1.0);
  const int i = std::min(static_cast<int>(std::floor(c)), std::max(n - 2, 0));
  const double a = c - i;
  if (a <= 0 || n == 1) return take.shapes[i];
  return (1 - a) * take.shapes[i] + a * take.shapes[i + 1];
}

// (1 - a) p + a q, component by component (headings are unwrapped).
RootTransform mix_roots(const RootTransform& p, const RootTransform& q, double a) {
  return {(1 - a) * p.x + a * q.x, (1 - a) * p.y + a * q.y, (1 - a) * p.heading + a * q.heading};
}

RootTransform root_at(const LocalTake& take, double x) {
  const int n = take.num_frames();
  const double c = std::clamp(x, 0.0, n - 1.0);
  const int i = std::min(static_cast<int>(std::floor(c)), std::max(n - 2, 0));
  const double a = c - i;
  if (a <= 0 || n == 1) return take.roots[i];
  return mix_roots(take.roots[i], take.roots[i + 1], a);
}

double shape_distance(const Eigen::Matrix3Xd& a, const Eigen::Matrix3Xd& b) {
  return (a - b).colwise().squaredNorm().mean();
}

namespace {

// Scores cycles of one take: the state (shape and velocity) distance between the frames at
// both ends of a candidate cycle, and the cycle's own variation.
class CycleScorer {
 public:
  explicit CycleScorer(const LocalTake& take) : take_(take), n_(take.num_frames()) {}

  int frames() const { return n_; }
  static double velocity_weight(double lag) { return std::pow(lag / (2 * std::numbers::pi), 2); }

  // Velocity at (fractional) frame x by one finite-difference stencil: 0 central, 1 forward,
  // -1 backward. The two ends of a cycle are compared with the same stencil, so that its error
  // (large for fast limbs at a low frame rate) cancels.
  Eigen::Matrix3Xd velocity(double x, int kind) const {
    if (kind == 0) return 0.5 * (shape_at(take_, x + 1) - shape_at(take_, x - 1));
    if (kind > 0) return shape_at(take_, x + 1) - shape_at(take_, x);
    return shape_at(take_, x) - shape_at(take_, x - 1);
  }

  struct Closure {
    double shape = 0, velocity = 0;
    double total(double w) const { return shape + w * velocity; }
  };
  // State distance between frame s and the state at s + p: shape, plus velocity. Where no
  // stencil fits at both ends (the cycle spans the whole take), the velocities are compared
  // across the seam: forward at the start minus backward at the end is, for a smooth join, the
  // second difference there, estimated from the neighbouring frames on both sides.
  Closure closure(int s, double p) const {
    Closure c;
    c.shape = shape_distance(take_.shapes[s], shape_at(take_, s + p));
    const bool before = s >= 1, after = s + p + 1 <= n_ - 1 + kEps;
    if (before || after) {
      const int kind = before && after ? 0 : after ? 1 : -1;
      c.velocity = shape_distance(velocity(s, kind), velocity(s + p, kind));
    } else {
      const Eigen::Matrix3Xd x0 = take_.shapes[s], x1 = shape_at(take_, s + 1),
                             x2 = shape_at(take_, s + 2), y0 = shape_at(take_, s + p),
                             y1 = shape_at(take_, s + p - 1), y2 = shape_at(take_, s + p - 2);
      const Eigen::Matrix3Xd jump = (x1 - x0) - (y0 - y1);
      c.velocity = shape_distance(jump, 0.5 * ((x2 - 2 * x1 + x0) + (y0 - 2 * y1 + y2)));
    }
    return c;
  }

  // Mean state distance between frames p apart, over every start that fits.
  double mean_at(double p) const {
    double sum = 0;
    int count = 0;
    for (int s = 0; s + p <= n_ - 1 + kEps; ++s, ++count) sum += closure(s, p).total(velocity_weight(p));
    return count ? sum / count : kInf;
  }

  // The same over the better half of the starts: robust to the stretches of a long take that
  // do not repeat (a pause, a turn), whose pairs would pollute the mean at every lag.
  double lower_half_at(double p) const {
    std::vector<double> d;
    for (int s = 0; s + p <= n_ - 1 + kEps; ++s) d.push_back(closure(s, p).total(velocity_weight(p)));
    if (d.empty()) return kInf;
    const std::size_t half = (d.size() + 1) / 2;
    std::nth_element(d.begin(), d.begin() + static_cast<std::ptrdiff_t>(half - 1), d.end());
    double sum = 0;
    for (std::size_t k = 0; k < half; ++k) sum += d[k];
    return sum / static_cast<double>(half);
  }

  // The cycle [s, s + p] with its closure and variation.
  Cycle evaluate(int s, double p) const {
    Cycle cycle;
    cycle.start = s;
    cycle.period = p;
    const Closure cl = closure(s, p);
    cycle.closure_rms = std::sqrt(cl.shape);
    // Variation of shape and (central) velocity over the cycle's frames.
    const int first = s;
    const int last = std::min(static_cast<int>(std::floor(s + p + kEps)), n_ - 1);
    Eigen::Matrix3Xd mean_x = Eigen::Matrix3Xd::Zero(3, take_.shapes[0].cols());
    Eigen::Matrix3Xd mean_v = mean_x;
    std::vector<Eigen::Matrix3Xd> v;
    for (int f = std::max(first, 1); f <= std::min(last, n_ - 2); ++f) v.push_back(velocity(f, 0));
    for (int f = first; f <= last; ++f) mean_x += take_.shapes[f] / (last - first + 1);
    for (const auto& x : v) mean_v += x / static_cast<double>(v.size());
    double var_x = 0, var_v = 0;
    for (int f = first; f <= last; ++f) var_x += shape_distance(take_.shapes[f], mean_x) / (last - first + 1);
    for (const auto& x : v) var_v += shape_distance(x, mean_v) / static_cast<double>(v.size());
    cycle.variation_rms = std::sqrt(var_x);
    const double w = velocity_weight(p);
    const double variation = !v.empty() ? var_x + w * var_v : var_x;
    cycle.closure_ratio = variation > 0 ? std::sqrt(cl.total(w) / variation) : kInf;
    return cycle;
  }

  // Fractional refinement of a period around p0 (+-radius frames, 0.1 steps and a parabola).
  double refine(double p0, double radius, double lowest) const {
    const double step = 0.1;
    double best_p = p0, best = mean_at(p0);
    for (double p = p0 - radius + step; p < p0 + radius - kEps; p += step) {
      if (p < lowest || p > n_ - 1 + kEps) continue;
      const double c = mean_at(p);
      if (c < best) best = c, best_p = p;
    }
    const double a = mean_at(best_p - step), c = mean_at(best_p + step);
    if (std::isfinite(a) && std::isfinite(c)) best_p += step * parabola_vertex(a, best, c);
    return std::min(best_p, n_ - 1.0);
  }

 private:
  static constexpr double kEps = 1e-9;
  const LocalTake& take_;
  int n_;
};

// The vertices of a take that move a lot but repeat at no lag (loose cloth in a chaotic swing,
// hair). Per vertex: its variation var (mean squared distance from its mean position) and,
// at every lag from min_cycle_frames on, whole and half frames, the mean squared distance c
// between its positions that lag apart; unrelated positions give c = 2 var. Loose: at no lag below
// kLooseRepeat^2 * 2 var, and a variation at least a quarter of the mean vertex's (a vertex
// that hardly moves is left in: its noise is no swing). Shape only: enough to tell the parts
// apart.
constexpr double kLooseRepeat = 0.25;

std::vector<bool> loose_vertices(const LocalTake& take, const CycleOptions& options) {
  const int n = take.num_frames();
  const Eigen::Index nv = take.shapes[0].cols();
  Eigen::Matrix3Xd mean = Eigen::Matrix3Xd::Zero(3, nv);
  for (const Eigen::Matrix3Xd& x : take.shapes) mean += x / n;
  Eigen::RowVectorXd var = Eigen::RowVectorXd::Zero(nv);
  for (const Eigen::Matrix3Xd& x : take.shapes) var += (x - mean).colwise().squaredNorm() / n;
  Eigen::RowVectorXd best = Eigen::RowVectorXd::Constant(nv, kInf);
  // Whole and half-frame lags (the half by linear interpolation): a fast limb of a cycle a
  // fractional number of frames long repeats at no whole lag much better than half a frame off.
  for (int lag = options.min_cycle_frames; lag <= n - 1; ++lag) {
    for (const bool half : {false, true}) {
      if (half && lag + 1 > n - 1) continue;
      Eigen::RowVectorXd c = Eigen::RowVectorXd::Zero(nv);
      int count = 0;
      for (int s = 0; s + lag + (half ? 1 : 0) <= n - 1; ++s, ++count) {
        const Eigen::Matrix3Xd& a = take.shapes[s];
        if (half) {
          c += (a - 0.5 * (take.shapes[s + lag] + take.shapes[s + lag + 1])).colwise().squaredNorm();
        } else {
          c += (a - take.shapes[s + lag]).colwise().squaredNorm();
        }
      }
      best = best.cwiseMin(c / count);
    }
  }
  const double mean_var = var.mean();
  std::vector<bool> loose(static_cast<std::size_t>(nv), false);
  for (Eigen::Index v = 0; v < nv; ++v) {
    loose[static_cast<std::size_t>(v)] = var[v] >= 0.25 * mean_var && best[v] > kLooseRepeat * kLooseRepeat * 2 * var[v];
  }
  return loose;
}

// The take without its loose vertices, when it has some and they are fewer than half: what
// the cycle is scored on. Without: nothing (score the take itself).
std::optional<LocalTake> periodic_part(const LocalTake& take, const CycleOptions& options) {
  if (take.num_frames() - 1 < options.min_cycle_frames) return std::nullopt;
  const std::vector<bool> loose = loose_vertices(take, options);
  std::vector<Eigen::Index> keep;
  for (std::size_t v = 0; v < loose.size(); ++v) {
    if (!loose[v]) keep.push_back(static_cast<Eigen::Index>(v));
  }
  if (keep.size() == loose.size() || 2 * keep.size() < loose.size()) return std::nullopt;
  LocalTake part = take;
  for (Eigen::Matrix3Xd& x : part.shapes) x = Eigen::Matrix3Xd(x(Eigen::all, keep));
  return part;
}

// A scorer of the take's periodic part (periodic_part), or of the take.
struct PeriodicScorer {
  std::optional<LocalTake> part;
  CycleScorer scorer;
  PeriodicScorer(const LocalTake& take, const CycleOptions& options)
      : part(periodic_part(take, options)), scorer(part ? *part : take) {}
  PeriodicScorer(const PeriodicScorer&) = delete;  // the scorer refers to `part`
  PeriodicScorer& operator=(const PeriodicScorer&) = delete;
};

void check_cycle_length(const LocalTake& take, const CycleOptions& options) {
  const int n = take.num_frames();
  if (n - 1 < options.min_cycle_frames || n < 3) {
    throw InputError(fmt::format("take {}: {} frames cannot hold a cycle of at least {} frames",
                                 take.name, n, std::max(options.min_cycle_frames, 2)));
  }
}

double find_period(const CycleScorer& scorer, const CycleOptions& options) {
  const int n = scorer.frames();
  std::vector<double> m(n, kInf);
  double lo = kInf;
  for (int lag = options.min_cycle_frames; lag <= n - 1; ++lag) {
    m[lag] = scorer.lower_half_at(lag);
    lo = std::min(lo, m[lag]);
  }
  auto local_min = [&](int lag) {
    return lag > options.min_cycle_frames && lag <= n - 1 && m[lag] <= m[lag - 1] &&
           (lag == n - 1 || m[lag] <= m[lag + 1]);
  };
  // The lowest local minimum: one period or a multiple of it.
  int best = -1;
  for (int lag = options.min_cycle_frames + 1; lag <= n - 1; ++lag) {
    if (local_min(lag) && (best < 0 || m[lag] < m[best])) best = lag;
  }
  if (best < 0) {
    best = static_cast<int>(std::min_element(m.begin(), m.end()) - m.begin());
    return scorer.refine(best, 1, options.min_cycle_frames);
  }
  // The lowest mean distance near x: at the lowest integer local minimum within +-radius of
  // x, refined to a fraction of a frame (an integer lag near a non-integer period repeats
  // worse than an integer multiple of it). Infinite if there is none.
  struct Near {
    double lag = -1, mean = kInf;
  };
  auto minimum_near = [&](double x) {
    const double radius = std::max(1.0, 0.12 * x);
    int found = -1;
    for (int lag = static_cast<int>(std::ceil(x - radius));
         lag <= static_cast<int>(std::floor(x + radius)); ++lag) {
      if (lag >= 0 && lag < n && local_min(lag) && (found < 0 || m[lag] < m[found])) found = lag;
    }
    Near near;
    if (found < 0) return near;
    near.lag = scorer.refine(found, 1, options.min_cycle_frames);
    near.mean = std::min(m[found], scorer.lower_half_at(near.lag));
    return near;
  };
  // A sub-multiple f = best / k is the period if the state repeats there about as well as at
  // `best`: within half as much again, plus 2 % of the range of the mean distance over the
  // lags up to f (longer lags weigh the velocity more, which inflates the range). A motion
  // whose shape nearly repeats at half its period (a quadruped's limb pairs in antiphase, a
  // walk's mirrored steps) repeats clearly worse at the half.
  const double best_mean = minimum_near(best).mean;
  double period = best;
  for (int k = 2; best / static_cast<double>(k) >= options.min_cycle_frames; ++k) {
    const double f = best / static_cast<double>(k);
    const Near at = minimum_near(f);
    double range = 0;
    for (int lag = options.min_cycle_frames; lag <= std::min(n - 1, static_cast<int>(f) + 1); ++lag) {
      range = std::max(range, m[lag] - lo);
    }
    if (at.mean <= 1.5 * best_mean + 0.02 * range) period = at.lag;
  }
  return scorer.refine(period, 1, options.min_cycle_frames);
}

}  // namespace

double find_period(const LocalTake& take, const CycleOptions& options) {
  check_cycle_length(take, options);
  return find_period(PeriodicScorer(take, options).scorer, options);
}

Cycle find_cycle(const LocalTake& take, const CycleOptions& options) {
  check_cycle_length(take, options);
  const PeriodicScorer periodic(take, options);
  const CycleScorer& scorer = periodic.scorer;
  const double period = find_period(scorer, options);
  const int n = take.num_frames();
  // The start where the cycle closes best, of those where the take moves: standing still (a
  // long take's pause) closes best of all, but its state varies less still (closure_ratio
  // above max_closure_ratio), and it is no cycle.
  const double w = CycleScorer::velocity_weight(period);
  std::vector<std::pair<double, int>> starts;
  for (int s = 0; s + period <= n - 1 + 1e-9; ++s) starts.emplace_back(scorer.closure(s, period).total(w), s);
  if (starts.empty()) starts.emplace_back(kInf, 0);
  std::stable_sort(starts.begin(), starts.end(),
                   [](const std::pair<double, int>& a, const std::pair<double, int>& b) { return a.first < b.first; });
  Cycle cycle = scorer.evaluate(starts.front().second, period);
  for (std::size_t k = 1; k < starts.size() && !(cycle.closure_ratio <= options.max_closure_ratio); ++k) {
    const Cycle next = scorer.evaluate(starts[k].second, period);
    if (next.closure_ratio <= options.max_closure_ratio) cycle = next;
  }
  if (!(cycle.closure_ratio <= options.max_closure_ratio)) {
    throw InputError(fmt::format(
        "take {}: cannot close a cycle: the best cycle (frames {:.2f} to {:.2f}, {:.2f} frames) "
        "ends {:.1f} mm RMS away from its start and its state (shape and motion) differs by "
        "{:.0f} % of its variation over the cycle (at most {:.0f} %). Is the take shorter than "
        "one cycle, or not cyclic?",
        take.name, cycle.start, cycle.start + cycle.period, cycle.period, 1000 * cycle.closure_rms,
        100 * cycle.closure_ratio, 100 * options.max_closure_ratio));
  }
  return cycle;
}

TakeSegments find_cycles(const LocalTake& take, const CycleOptions& options) {
  TakeSegments out;
  const int n = take.num_frames();
  auto whole_take_one_shot = [&] {
    out.cycles.clear();
    out.one_shots = {{0, n - 1}};
  };
  if (n - 1 < options.min_cycle_frames || n < 3) {
    if (n >= 2) whole_take_one_shot();
    return out;
  }
  const PeriodicScorer periodic(take, options);
  const CycleScorer& scorer = periodic.scorer;
  out.period = find_period(scorer, options);
  // Every start's best closing cycle, its length within 15 % of the period (a long take's pace
  // drifts).
  std::vector<Cycle> candidates;
  const double radius = std::max(1.0, 0.15 * out.period);
  for (int s = 0; s + options.min_cycle_frames <= n - 1; ++s) {
    double best_p = -1, best = kInf;
    for (double p = out.period - radius; p <= out.period + radius + 1e-9; p += 0.25) {
      if (p < options.min_cycle_frames || s + p > n - 1 + 1e-9) continue;
      const double c = scorer.closure(s, p).total(CycleScorer::velocity_weight(p));
      if (c < best) best = c, best_p = p;
    }
    if (best_p < 0) continue;
    const Cycle c = scorer.evaluate(s, best_p);
    if (c.closure_ratio <= options.max_closure_ratio) candidates.push_back(c);
  }
  // The best closing cycles first, none overlapping another (they may share an end frame).
  std::sort(candidates.begin(), candidates.end(),
            [](const Cycle& a, const Cycle& b) { return a.closure_ratio < b.closure_ratio; });
  for (const Cycle& c : candidates) {
    bool overlaps = false;
    for (const Cycle& k : out.cycles) {
      overlaps = overlaps || (c.start < k.start + k.period - 0.5 && k.start < c.start + c.period - 0.5);
    }
    if (!overlaps) out.cycles.push_back(c);
  }
  std::sort(out.cycles.begin(), out.cycles.end(),
            [](const Cycle& a, const Cycle& b) { return a.start < b.start; });
  // What no cycle covers, in whole frames, as one-shot segments.
  int next = 0;
  auto gap = [&](int first, int last) {
    if (last - first >= options.min_cycle_frames) out.one_shots.push_back({first, last});
  };
  for (const Cycle& c : out.cycles) {
    gap(next, static_cast<int>(std::floor(c.start)));
    next = static_cast<int>(std::ceil(c.start + c.period - 1e-9));
  }
  gap(next, n - 1);
  return out;
}


TakeTiming one_shot_timing(const LocalTake& take) {
  return TakeTiming{false, 0.0, static_cast<double>(take.num_frames() - 1)};
}

TakeTiming cyclic_timing(const Cycle& cycle) { return TakeTiming{true, cycle.start, cycle.period}; }

Eigen::Matrix3Xd shape_at_phase(const LocalTake& take, const TakeTiming& timing, double u) {
  if (!timing.cyclic) return shape_at(take, timing.frame_at(u));
  const double f = u - std::floor(u);
  const Eigen::Matrix3Xd gap =
      shape_at(take, timing.start + timing.length) - shape_at(take, timing.start);
  return shape_at(take, timing.start + f * timing.length) - f * gap;
}

RootTransform root_at_phase(const LocalTake& take, const TakeTiming& timing, double u) {
  if (!timing.cyclic) return root_at(take, timing.frame_at(u));
  const double whole = std::floor(u);
  RootTransform r = root_at(take, timing.start + (u - whole) * timing.length);
  // One cycle later the body repeats its motion relative to where the cycle started:
  // root(x + period) = W root(x) with W = root(end) root(start)^-1.
  const RootTransform w = root_compose(root_at(take, timing.start + timing.length),
                                      root_inverse(root_at(take, timing.start)));
  const RootTransform step = whole >= 0 ? w : root_inverse(w);
  for (int k = 0; k < std::abs(static_cast<int>(whole)); ++k) r = root_compose(step, r);
  return r;
}

LocalTake steady_cycle_root(LocalTake take, const TakeTiming& timing, const CycleOptions& options) {
  const int n = take.num_frames();
  const double start = timing.start, period = timing.length;
  // Roots about the take's mean position c, so that a heading error of W does not turn into a
  // translation error the size of the distance from the world's origin.
  Eigen::Vector2d c = Eigen::Vector2d::Zero();
  for (const RootTransform& r : take.roots) c += Eigen::Vector2d(r.x, r.y) / n;
  auto centred = [&](RootTransform r) {
    r.x -= c.x();
    r.y -= c.y();
    return r;
  };
  // Mean motion per cycle; the sway, periodic, cancels in each root(x + period) root(x)^-1.
  const std::vector<RootTransform>& raw = take.raw_roots.empty() ? take.roots : take.raw_roots;
  auto raw_at = [&](double x) {
    const int i = std::min(static_cast<int>(std::floor(x)), n - 2);
    const double a = std::clamp(x - i, 0.0, 1.0);
    return mix_roots(raw[i], raw[i + 1], a);
  };
  // Over the frames that loop: a long take's stands and the steps into and out of them would
  // slow the mean down. [x, x + period] loops if it closes as a cycle would (find_cycles).
  const PeriodicScorer periodic(take, options);
  auto loops = [&](int x) { return periodic.scorer.evaluate(x, period).closure_ratio <= options.max_closure_ratio; };
  RootTransform w;
  int count = 0;
  for (const bool all : {false, true}) {
    for (int x = 0; x + period <= n - 1 + 1e-9; ++x) {
      if (!all && !loops(x)) continue;
      const RootTransform motion = root_compose(centred(raw_at(x + period)), root_inverse(centred(raw[x])));
      w = {w.x + motion.x, w.y + motion.y, w.heading + motion.heading};
      ++count;
    }
    if (count > 0) break;
  }
  if (count == 0) {
    throw InputError(fmt::format("take {}: its cycle ({:.2f} frames) is longer than the take",
                                 take.name, period));
  }
  w = {w.x / count, w.y / count, w.heading / count};
  // The steady root at the cycle's start, s, from the means over the cycle (midpoint samples):
  // heading(x_j) = s.heading + a_j w.heading, position(x_j) = R(a_j w.heading) s.position + t_j
  // with (t_j, a_j w.heading) = root_power(w, a_j).
  const int samples = std::max(8, static_cast<int>(std::ceil(8 * period)));
  double heading = 0;
  Eigen::Vector2d position = Eigen::Vector2d::Zero(), shift = Eigen::Vector2d::Zero();
  double mean_cos = 0, mean_sin = 0;
  for (int j = 0; j < samples; ++j) {
    const double a = (j + 0.5) / samples;
    const RootTransform r = centred(root_at(take, start + a * period));
    const RootTransform step = root_power(w, a);
    heading += (r.heading - step.heading) / samples;
    position += Eigen::Vector2d(r.x, r.y) / samples;
    shift += Eigen::Vector2d(step.x, step.y) / samples;
    mean_cos += std::cos(step.heading) / samples;
    mean_sin += std::sin(step.heading) / samples;
  }
  // Solve [mean_cos -mean_sin; mean_sin mean_cos] s.position = position - shift.
  const Eigen::Vector2d rhs = position - shift;
  const double det = mean_cos * mean_cos + mean_sin * mean_sin;
  if (!(det > 1e-6)) {
    throw InputError(fmt::format("take {}: turns {:.0f} degrees per cycle; a steady root needs less "
                                 "than a full turn",
                                 take.name, w.heading * 180 / std::numbers::pi));
  }
  const RootTransform root_start{(mean_cos * rhs.x() + mean_sin * rhs.y()) / det,
                                 (-mean_sin * rhs.x() + mean_cos * rhs.y()) / det, heading};
  for (int f = 0; f < n; ++f) {
    RootTransform steady = root_compose(root_power(w, (f - start) / period), root_start);
    steady.x += c.x();
    steady.y += c.y();
    take.shapes[f] = apply_root(take.shapes[f], root_relative(steady, take.roots[f]));
    take.roots[f] = steady;
  }
  take.raw_roots.clear();
  return take;
}



Warp identity_warp(int intervals) {
  Warp w;
  w.knots.resize(intervals + 1);
  for (int i = 0; i <= intervals; ++i) w.knots[i] = static_cast<double>(i) / intervals;
  return w;
}

Warp register_take(const LocalTake& reference, const TakeTiming& reference_timing,
                   const LocalTake& take, const TakeTiming& timing, const WarpOptions& options) {
  const bool cyclic = reference_timing.cyclic;
  const int m = std::max(4, static_cast<int>(std::lround(options.oversample *
                                                          reference_timing.length)));
  const std::vector<Eigen::Matrix3Xd> a = sample_phases(reference, reference_timing, 0, m, m + 1);
  const std::vector<Eigen::Matrix3Xd> va = phase_velocities(a, cyclic);
  // Each take's poses as deviations from its own mean pose (centre_poses): the takes of a class
  // differ by what the blend interpolates (an arm reaching low or high, a longer stride), and
  // that constant difference must not decide which phases correspond; how the pose moves does.
  auto shapes = [&](const std::vector<Eigen::Matrix3Xd>& s) {
    Eigen::MatrixXd x = stack(s);
    if (options.center_poses) x.colwise() -= x.rowwise().mean();
    return x;
  };
  const Eigen::MatrixXd xa = shapes(a), xva = stack(va);
  auto distances = [&](const std::vector<Eigen::Matrix3Xd>& b) {
    return Eigen::MatrixXd(pairwise_distances(xa, shapes(b)) +
                           options.velocity_weight *
                               pairwise_distances(xva, stack(phase_velocities(b, cyclic))));
  };

  Warp warp;
  if (cyclic) {
    // Circular search for the phase offset under a uniform warp, refined by a parabola.
    const Eigen::MatrixXd d = distances(sample_phases(take, timing, 0, m, m + 1));
    std::vector<double> cost(m, 0.0);
    for (int o = 0; o < m; ++o) {
      for (int i = 0; i < m; ++i) cost[o] += d(i, (i + o) % m);
    }
    const int best = static_cast<int>(std::min_element(cost.begin(), cost.end()) - cost.begin());
    const double delta =
        parabola_vertex(cost[(best - 1 + m) % m], cost[best], cost[(best + 1) % m]);
    warp.offset = (best + delta) / m;
    warp.offset -= std::floor(warp.offset);
  }
  const Eigen::MatrixXd d = distances(sample_phases(take, timing, warp.offset, m, m + 1));
  std::vector<double> path = dtw_path(d, options.slope_penalty);
  for (double& p : path) p /= m;
  for (int pass = 0; pass < options.smoothing; ++pass) {
    std::vector<double> s = path;
    for (int i = 1; i < m; ++i) s[i] = 0.25 * (path[i - 1] + 2 * path[i] + path[i + 1]);
    path = s;
  }
  // Strictly increasing from 0 to 1, so the warp can be inverted.
  path.front() = 0;
  const double tiny = 1e-6 / m;
  for (int i = 1; i <= m; ++i) path[i] = std::max(path[i], path[i - 1] + tiny);
  const double end = path.back();
  for (double& p : path) p /= end;
  warp.knots = std::move(path);
  return warp;
}

}  // namespace fourd::timewarp
