#include "stages/reconstruct/depth_map.h"

#include <algorithm>
#include <cmath>
#include <numeric>
#include <opencv2/imgproc.hpp>
#include <tbb/parallel_for.h>

#include "pipeline/core/error.h"

namespace fourd::reconstruct {

void DepthMapOptions::check() const {
  if (step >= search_depth) throw ConfigError("step must be smaller than search_depth");
  if (neighbour_score != "mean" && neighbour_score != "best") {
    throw ConfigError("neighbour_score '" + neighbour_score + "': expected mean or best");
  }
}

std::vector<int> select_neighbours(const std::vector<PinholeCamera>& cameras, int ref, int count,
                                   double max_angle_deg) {
  std::vector<std::pair<double, int>> by_angle;
  const Eigen::Vector3d axis = cameras[ref].axis();
  for (int j = 0; j < static_cast<int>(cameras.size()); ++j) {
    if (j == ref) continue;
    double angle = std::acos(std::clamp(axis.dot(cameras[j].axis()), -1.0, 1.0)) * 180 / M_PI;
    if (angle <= max_angle_deg) by_angle.emplace_back(angle, j);
  }
  std::sort(by_angle.begin(), by_angle.end());
  std::vector<int> out;
  for (int k = 0; k < std::min<int>(count, by_angle.size()); ++k) out.push_back(by_angle[k].second);
  return out;
}

namespace {

// Unnormalised box sums over the matching window.
void window_sum(const cv::Mat& src, cv::Mat& dst, int radius) {
  cv::boxFilter(src, dst, CV_32F, cv::Size(2 * radius + 1, 2 * radius + 1), cv::Point(-1, -1),
                false, cv::BORDER_CONSTANT);
}

// What the sweep keeps per pixel while it runs: the best score so far and the scores just
// before and after it, for the parabola.
struct Best {
  cv::Mat score, before, after, index;
  cv::Mat previous;          // score of the previous hypothesis
  cv::Mat after_pending;     // 1 while the hypothesis after the best is still to come
};

cv::Mat prefiltered(const cv::Mat& gray, const DepthMapOptions& options) {
  if (options.prefilter_sigma <= 0) return gray;
  cv::Mat blurred;
  cv::GaussianBlur(gray, blurred, cv::Size(), options.prefilter_sigma);
  return blurred;
}

// The reference view on the hull's rectangle grown by the window (so windows never leave it)
// and its window statistics over silhouette pixels.
struct Reference {
  cv::Rect roi;
  cv::Size size;
  cv::Mat gray, hull;
  cv::Mat mask;  // CV_8U 0/1
  cv::Mat m;     // the mask as CV_32F
  cv::Mat s_m, s_g, s_gg;
  cv::Mat ref_var;  // variance term (sum of squared deviations)
  cv::Mat usable;   // pixels worth matching
};

Reference reference_window(const StereoView& view, const DepthMapOptions& options) {
  const PinholeCamera& cam = view.camera;
  const int r = options.window_radius;
  Reference ref;
  cv::Rect& roi = ref.roi;
  roi = cv::Rect(view.roi.x - r - 1, view.roi.y - r - 1, view.roi.width + 2 * r + 2,
                 view.roi.height + 2 * r + 2);
  roi &= cv::Rect(0, 0, cam.width, cam.height);
  const cv::Size size = ref.size = roi.size();
  ref.gray = prefiltered(view.gray, options)(roi).clone();
  ref.hull = view.hull_depth(roi);
  ref.mask = cv::Mat(ref.hull > 0) / 255;
  ref.mask.convertTo(ref.m, CV_32F);

  // Window statistics of the reference image (over silhouette pixels only).
  cv::Mat mg = ref.m.mul(ref.gray);
  window_sum(ref.m, ref.s_m, r);
  window_sum(mg, ref.s_g, r);
  window_sum(mg.mul(ref.gray), ref.s_gg, r);
  const float window_area = static_cast<float>((2 * r + 1) * (2 * r + 1));
  // Reference variance term (sum of squared deviations), and pixels worth matching.
  ref.ref_var = cv::Mat(size, CV_32F);
  ref.usable = cv::Mat(size, CV_8U, cv::Scalar(0));
  for (int y = 0; y < size.height; ++y) {
    const float *sm = ref.s_m.ptr<float>(y), *sg = ref.s_g.ptr<float>(y), *sgg = ref.s_gg.ptr<float>(y);
    const std::uint8_t* mk = ref.mask.ptr<std::uint8_t>(y);
    float* v = ref.ref_var.ptr<float>(y);
    std::uint8_t* u = ref.usable.ptr<std::uint8_t>(y);
    for (int x = 0; x < size.width; ++x) {
      v[x] = sm[x] > 0 ? std::max(0.f, sgg[x] - sg[x] * sg[x] / sm[x]) : 0.f;
      u[x] = mk[x] && sm[x] >= options.min_window_fill * window_area &&
             v[x] >= options.min_texture * options.min_texture * sm[x];
    }
  }
  return ref;
}

// A neighbour: the ray direction of each reference pixel in the neighbour's camera frame (a),
// and the reference centre there (b): X_j = depth * a + b.
struct Neighbour {
  const StereoView* view;
  cv::Mat gray;
  Eigen::Matrix3d rotation;  // neighbour_from_reference
  Eigen::Vector3d offset;
};

std::vector<Neighbour> neighbour_views(const std::vector<StereoView>& views,
                                       const std::vector<int>& neighbours,
                                       const PinholeCamera& cam, const DepthMapOptions& options) {
  std::vector<Neighbour> nbs;
  for (int j : neighbours) {
    Neighbour n;
    n.view = &views[j];
    n.gray = prefiltered(views[j].gray, options);
    n.rotation = views[j].camera.R * cam.R.transpose();
    n.offset = views[j].camera.t - n.rotation * cam.t;
    nbs.push_back(std::move(n));
  }
  return nbs;
}

// The sweep's images: one hypothesis's scratch and the running best.
struct Sweep {
  explicit Sweep(cv::Size size)
      : map_x(size, CV_32F), map_y(size, CV_32F), visible(size, CV_8U),
        sum_ncc(size, CV_32F), count(size, CV_32F) {
    best.score = cv::Mat(size, CV_32F, cv::Scalar(-2));
    best.before = cv::Mat(size, CV_32F, cv::Scalar(-2));
    best.after = cv::Mat(size, CV_32F, cv::Scalar(-2));
    best.index = cv::Mat(size, CV_32S, cv::Scalar(-1));
    best.previous = cv::Mat(size, CV_32F, cv::Scalar(-2));
    best.after_pending = cv::Mat(size, CV_8U, cv::Scalar(0));
  }
  cv::Mat map_x, map_y, visible;
  cv::Mat warped, mw, s_w, s_ww, s_gw;
  cv::Mat sum_ncc, count;
  Best best;
};

// Where each reference pixel's hypothesis (the hull's depth + `offset`) lands in the
// neighbour, and whether the neighbour can see it (not far behind its own hull surface there).
void project_hypothesis(const Reference& ref, const Neighbour& nb, const Eigen::Matrix3d& k_inv,
                        double offset, const DepthMapOptions& options, Sweep& s) {
  const cv::Rect& roi = ref.roi;
  const cv::Size size = ref.size;
  const PinholeCamera& ncam = nb.view->camera;
  const cv::Mat& nhull = nb.view->hull_depth;
  for (int y = 0; y < size.height; ++y) {
    const float* h = ref.hull.ptr<float>(y);
    float* mx = s.map_x.ptr<float>(y);
    float* my = s.map_y.ptr<float>(y);
    std::uint8_t* vis = s.visible.ptr<std::uint8_t>(y);
    for (int x = 0; x < size.width; ++x) {
      vis[x] = 0;
      mx[x] = my[x] = -1000.f;
      if (h[x] <= 0) continue;
      const double depth = h[x] + offset;
      Eigen::Vector3d ray = k_inv * Eigen::Vector3d(roi.x + x + 0.5, roi.y + y + 0.5, 1.0);
      Eigen::Vector3d p = depth * (nb.rotation * ray) + nb.offset;
      if (p.z() <= 1e-6) continue;
      Eigen::Vector2d px = ncam.pixel(p);
      mx[x] = static_cast<float>(px.x() - 0.5);
      my[x] = static_cast<float>(px.y() - 0.5);
      if (!ncam.in_image(px)) continue;
      float nh = nhull.at<float>(static_cast<int>(px.y()), static_cast<int>(px.x()));
      vis[x] = nh > 0 && p.z() <= nh + options.occlusion_margin;
    }
  }
}

// The neighbour's NCC with the reference at the projected hypothesis, added to the pixels'
// sum (or kept when it is the best neighbour's so far).
void add_ncc(const Reference& ref, const Neighbour& nb, const DepthMapOptions& options,
             bool best_neighbour, Sweep& s) {
  const int r = options.window_radius;
  const cv::Size size = ref.size;
  cv::remap(nb.gray, s.warped, s.map_x, s.map_y, cv::INTER_LINEAR, cv::BORDER_CONSTANT, 0);
  s.mw = ref.m.mul(s.warped);
  window_sum(s.mw, s.s_w, r);
  window_sum(s.mw.mul(s.warped), s.s_ww, r);
  window_sum(s.mw.mul(ref.gray), s.s_gw, r);
  for (int y = 0; y < size.height; ++y) {
    const std::uint8_t* u = ref.usable.ptr<std::uint8_t>(y);
    const std::uint8_t* vis = s.visible.ptr<std::uint8_t>(y);
    const float *sm = ref.s_m.ptr<float>(y), *sg = ref.s_g.ptr<float>(y), *rv = ref.ref_var.ptr<float>(y);
    const float *sw = s.s_w.ptr<float>(y), *sww = s.s_ww.ptr<float>(y), *sgw = s.s_gw.ptr<float>(y);
    float* sn = s.sum_ncc.ptr<float>(y);
    float* cn = s.count.ptr<float>(y);
    for (int x = 0; x < size.width; ++x) {
      if (!u[x] || !vis[x]) continue;
      const float var_w = sww[x] - sw[x] * sw[x] / sm[x];
      const float cov = sgw[x] - sg[x] * sw[x] / sm[x];
      const float denom = std::sqrt(std::max(var_w, 1e-6f) * rv[x]);
      const float ncc = cov / denom;
      if (!best_neighbour) {
        sn[x] += ncc;
        cn[x] += 1;
      } else if (cn[x] == 0 || ncc > sn[x]) {
        sn[x] = ncc;
        cn[x] = 1;
      }
    }
  }
}

// Track the best hypothesis per pixel: hypothesis k's score against the best so far.
void track_best(int k, const cv::Size size, Sweep& s) {
  Best& best = s.best;
  for (int y = 0; y < size.height; ++y) {
    const float* sn = s.sum_ncc.ptr<float>(y);
    const float* cn = s.count.ptr<float>(y);
    float* bs = best.score.ptr<float>(y);
    float* bb = best.before.ptr<float>(y);
    float* ba = best.after.ptr<float>(y);
    int* bi = best.index.ptr<int>(y);
    float* prev = best.previous.ptr<float>(y);
    std::uint8_t* pending = best.after_pending.ptr<std::uint8_t>(y);
    for (int x = 0; x < size.width; ++x) {
      const float sc = cn[x] > 0 ? sn[x] / cn[x] : -2.f;
      if (pending[x]) {
        ba[x] = sc;
        pending[x] = 0;
      }
      if (cn[x] > 0 && sc > bs[x]) {
        bs[x] = sc;
        bb[x] = prev[x];
        bi[x] = k;
        pending[x] = 1;
      }
      prev[x] = sc;
    }
  }
}

// Depth at the best hypothesis, refined by a parabola through its neighbours' scores. A best
// at either end of the range is not a peak: the surface may lie beyond it.
void refine_depths(const Reference& ref, const Best& best, int hypotheses,
                   const DepthMapOptions& options, DepthMap& out) {
  const cv::Rect& roi = ref.roi;
  const cv::Size size = ref.size;
  for (int y = 0; y < size.height; ++y) {
    const float* h = ref.hull.ptr<float>(y);
    const std::uint8_t* u = ref.usable.ptr<std::uint8_t>(y);
    const float* bs = best.score.ptr<float>(y);
    const float* bb = best.before.ptr<float>(y);
    const float* ba = best.after.ptr<float>(y);
    const int* bi = best.index.ptr<int>(y);
    float* depth = out.depth.ptr<float>(roi.y + y) + roi.x;
    float* score = out.score.ptr<float>(roi.y + y) + roi.x;
    for (int x = 0; x < size.width; ++x) {
      if (!u[x] || bi[x] <= 0 || bi[x] >= hypotheses - 1) continue;
      if (bs[x] < options.min_ncc || bb[x] < -1.5f || ba[x] < -1.5f) continue;
      const double curvature = bb[x] - 2.0 * bs[x] + ba[x];
      double delta = curvature < 0 ? 0.5 * (bb[x] - ba[x]) / curvature : 0.0;
      delta = std::clamp(delta, -0.5, 0.5);
      depth[x] = static_cast<float>(h[x] - options.front_margin + (bi[x] + delta) * options.step);
      score[x] = bs[x];
    }
  }
}

}  // namespace

DepthMap estimate_depth_map(const std::vector<StereoView>& views, int ref,
                            const std::vector<int>& neighbours, const DepthMapOptions& options) {
  const StereoView& view = views[ref];
  const PinholeCamera& cam = view.camera;
  DepthMap out;
  out.depth = cv::Mat::zeros(cam.height, cam.width, CV_32F);
  out.score = cv::Mat(cam.height, cam.width, CV_32F, cv::Scalar(-1));
  if (view.roi.empty() || neighbours.empty()) return out;

  const Reference reference = reference_window(view, options);
  const std::vector<Neighbour> nbs = neighbour_views(views, neighbours, cam, options);
  const Eigen::Matrix3d k_inv = cam.K.inverse();
  const int hypotheses =
      static_cast<int>(std::floor((options.front_margin + options.search_depth) / options.step)) + 1;
  Sweep sweep(reference.size);
  const bool best_neighbour = options.neighbour_score == "best";
  for (int k = 0; k < hypotheses; ++k) {
    const double offset = -options.front_margin + k * options.step;
    sweep.sum_ncc.setTo(0);
    sweep.count.setTo(0);
    for (const Neighbour& nb : nbs) {
      project_hypothesis(reference, nb, k_inv, offset, options, sweep);
      add_ncc(reference, nb, options, best_neighbour, sweep);
    }
    track_best(k, reference.size, sweep);
  }
  refine_depths(reference, sweep.best, hypotheses, options, out);
  return out;
}

std::size_t keep_consistent_depths(const std::vector<PinholeCamera>& cameras,
                                   std::vector<DepthMap>& maps, int min_views, double tolerance) {
  if (min_views <= 0) return 0;
  const int n = static_cast<int>(maps.size());
  std::vector<cv::Mat> rejected(n);
  tbb::parallel_for(0, n, [&](int i) {
    const cv::Mat& depth = maps[i].depth;
    rejected[i] = cv::Mat::zeros(depth.size(), CV_8U);
    for (int y = 0; y < depth.rows; ++y) {
      const float* d = depth.ptr<float>(y);
      for (int x = 0; x < depth.cols; ++x) {
        if (d[x] <= 0) continue;
        const Eigen::Vector3d p = cameras[i].unproject(x + 0.5, y + 0.5, d[x]);
        int agree = 0;
        for (int j = 0; j < n && agree < min_views; ++j) {
          if (j == i || maps[j].depth.empty()) continue;
          const Eigen::Vector3d c = cameras[j].to_camera(p);
          if (c.z() <= 0) continue;
          const Eigen::Vector2d px = cameras[j].pixel(c);
          if (!cameras[j].in_image(px)) continue;
          const float dj =
              maps[j].depth.at<float>(static_cast<int>(px.y()), static_cast<int>(px.x()));
          if (dj > 0 && std::abs(dj - c.z()) <= tolerance) ++agree;
        }
        if (agree < min_views) rejected[i].at<std::uint8_t>(y, x) = 1;
      }
    }
  });
  std::size_t removed = 0;
  for (int i = 0; i < n; ++i) {
    removed += cv::countNonZero(rejected[i]);
    maps[i].depth.setTo(0, rejected[i]);
    maps[i].score.setTo(-1, rejected[i]);
  }
  return removed;
}

cv::Mat depth_map_normals(const PinholeCamera& camera, const cv::Mat& depth, double max_jump) {
  cv::Mat normals = cv::Mat::zeros(depth.size(), CV_32FC3);
  auto point = [&](int x, int y) { return camera.unproject(x + 0.5, y + 0.5, depth.at<float>(y, x)); };
  const Eigen::Vector3d centre = camera.center();
  for (int y = 1; y + 1 < depth.rows; ++y) {
    for (int x = 1; x + 1 < depth.cols; ++x) {
      const float d = depth.at<float>(y, x);
      if (d <= 0) continue;
      const float l = depth.at<float>(y, x - 1), rr = depth.at<float>(y, x + 1);
      const float up = depth.at<float>(y - 1, x), dn = depth.at<float>(y + 1, x);
      if (l <= 0 || rr <= 0 || up <= 0 || dn <= 0) continue;
      if (std::abs(l - d) > max_jump || std::abs(rr - d) > max_jump || std::abs(up - d) > max_jump ||
          std::abs(dn - d) > max_jump) {
        continue;
      }
      Eigen::Vector3d n = (point(x + 1, y) - point(x - 1, y)).cross(point(x, y + 1) - point(x, y - 1));
      if (!(n.norm() > 0)) continue;
      n.normalize();
      if (n.dot(centre - point(x, y)) < 0) n = -n;
      normals.at<cv::Vec3f>(y, x) = cv::Vec3f(n.x(), n.y(), n.z());
    }
  }
  return normals;
}

}  // namespace fourd::reconstruct
