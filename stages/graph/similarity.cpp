#include "stages/graph/similarity.h"

#include <fmt/format.h>
#include <tbb/parallel_for.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <vector>

#include "pipeline/core/error.h"
#include "pipeline/core/se2.h"

namespace fourd::graph {

namespace {

// Root-free positions of one frame (planes x | y | z with `stride`) into 3 #V planes.
void copy_planes(const float* frame, int nv, int stride, float* out) {
  for (int c = 0; c < 3; ++c) std::copy_n(frame + c * stride, nv, out + c * nv);
}

// out = (x - A prev) * scale, A the ground-plane motion `a` (z unchanged); planes of #V.
void velocity(const float* x, const float* prev, int nv, const RootPose& a, float scale,
              float* out) {
  const float c = std::cos(a.heading), s = std::sin(a.heading);
  for (int v = 0; v < nv; ++v) {
    const float px = c * prev[v] - s * prev[nv + v] + a.x;
    const float py = s * prev[v] + c * prev[nv + v] + a.y;
    out[v] = (x[v] - px) * scale;
    out[nv + v] = (x[nv + v] - py) * scale;
    out[2 * nv + v] = (x[2 * nv + v] - prev[2 * nv + v]) * scale;
  }
}

}  // namespace

Eigen::MatrixXf input_features(const MotionSpace& space, int input,
                               const SimilarityDefinition& definition) {
  const BlendSpace& b = space.blend;
  const int nv = b.num_vertices, f = b.num_frames;
  Eigen::MatrixXf out = Eigen::MatrixXf::Zero(6 * nv, f);
  const float root_w = static_cast<float>(std::sqrt(definition.velocity_weight));
  for (int u = 0; u < f; ++u) copy_planes(b.frame(input, u), nv, b.plane_stride, out.col(u).data());
  if (f < 2) return out;
  // Velocity at sample u from sample `prev` whose root, seen from sample u's root, is `a`.
  auto fill = [&](int u, int prev, const RootPose& a, double seconds) {
    const float scale = root_w * static_cast<float>(definition.frame_time / seconds);
    velocity(out.col(u).data(), out.col(prev).data(), nv, a, scale, out.col(u).data() + 3 * nv);
  };
  for (int u = 1; u < f; ++u) {
    fill(u, u - 1, root_relative(space.root(input, u), space.root(input, u - 1)),
         space.time(input, u) - space.time(input, u - 1));
  }
  if (space.cyclic && f >= 3) {
    // Sample 0 is sample F - 1 of the previous cycle: its predecessor is sample F - 2.
    fill(0, f - 2, root_relative(space.root(input, f - 1), space.root(input, f - 2)),
         space.time(input, f - 1) - space.time(input, f - 2));
  } else {
    out.col(0).tail(3 * nv) = out.col(1).tail(3 * nv);
  }
  return out;
}

Eigen::VectorXf played_state_features(const MotionSpace& space, double t, std::span<const float> w,
                                      const SimilarityDefinition& definition,
                                      MotionSample* scratch) {
  const int nv = space.blend.num_vertices, stride = space.blend.plane_stride;
  Eigen::VectorXf out = Eigen::VectorXf::Zero(6 * nv);
  evaluate_motion_space_weights(space, t, w, scratch);
  copy_planes(scratch->shape.data.data(), nv, stride, out.data());
  const double seconds_per_t = scratch->seconds_per_t;
  if (!(seconds_per_t > 0)) return out;
  const double dt = definition.frame_time / seconds_per_t;
  // The velocity over one frame ending at t_b, starting at t_a.
  double ta = t - dt, tb = t;
  if (!space.cyclic && ta < 0) {
    ta = 0;
    tb = std::min(1.0, dt);
  }
  const std::span<const float> pw(scratch->weights.data(), space.num_inputs());
  const RootPose a = root_relative(space_root(space, tb, pw), space_root(space, ta, pw));
  Eigen::VectorXf xa(3 * nv), xb(3 * nv);
  blend_hybrid(space.blend, space.cyclic ? wrap01(ta) : ta, pw, &scratch->shape);
  copy_planes(scratch->shape.data.data(), nv, stride, xa.data());
  if (tb == t) {
    xb = out.head(3 * nv);
  } else {
    blend_hybrid(space.blend, tb, pw, &scratch->shape);
    copy_planes(scratch->shape.data.data(), nv, stride, xb.data());
  }
  const float scale =
      static_cast<float>(std::sqrt(definition.velocity_weight) * dt / std::max(tb - ta, 1e-12));
  velocity(xb.data(), xa.data(), nv, a, scale, out.data() + 3 * nv);
  return out;
}

Eigen::VectorXf linear_state_features(std::span<const Eigen::MatrixXf> features, double t,
                                      std::span<const float> w) {
  const Eigen::Index f = features.front().cols();
  const double pos = std::clamp(t, 0.0, 1.0) * std::max<Eigen::Index>(f - 1, 0);
  const Eigen::Index u = std::min<Eigen::Index>(static_cast<Eigen::Index>(pos), std::max<Eigen::Index>(f - 2, 0));
  const float a = f < 2 ? 0.f : static_cast<float>(pos - u);
  const Eigen::Index u1 = std::min<Eigen::Index>(u + 1, f - 1);
  float sum = 0;
  for (std::size_t i = 0; i < features.size(); ++i) sum += std::max(0.f, w[i]);
  Eigen::VectorXf out = Eigen::VectorXf::Zero(features.front().rows());
  for (std::size_t i = 0; i < features.size(); ++i) {
    const float wi = sum > 0 ? std::max(0.f, w[i]) / sum : 1.f / features.size();
    out += wi * ((1 - a) * features[i].col(u) + a * features[i].col(u1));
  }
  return out;
}

double feature_distance(const Eigen::VectorXf& a, const Eigen::VectorXf& b) {
  return (a - b).cast<double>().squaredNorm() / (a.size() / 6.0);
}

EdgeSimilarity build_edge_similarity(const MotionSpace& source, const MotionSpace& target,
                                     const SimilarityDefinition& definition) {
  if (source.blend.num_vertices != target.blend.num_vertices) {
    throw InputError(fmt::format("similarity '{}' -> '{}': {} vs {} vertices", source.name,
                                 target.name, source.blend.num_vertices,
                                 target.blend.num_vertices));
  }
  const int ns = source.num_inputs(), nt = target.num_inputs();
  const int fs = source.num_samples(), ft = target.num_samples();
  const double nv = source.blend.num_vertices;
  std::vector<Eigen::MatrixXd> a(ns), b(nt);
  tbb::parallel_for(0, ns + nt, [&](int k) {
    if (k < ns) {
      a[k] = input_features(source, k, definition).cast<double>();
    } else {
      b[k - ns] = input_features(target, k - ns, definition).cast<double>();
    }
  });
  // d_ij(u, v) = (|a_u|^2 + |b_v|^2 - 2 a_u . b_v) / #V, one matrix product per input pair.
  std::vector<Eigen::MatrixXd> d(static_cast<std::size_t>(ns) * nt);
  tbb::parallel_for(0, ns * nt, [&](int k) {
    const Eigen::MatrixXd& x = a[k / nt];
    const Eigen::MatrixXd& y = b[k % nt];
    Eigen::MatrixXd g = -2.0 * x.transpose() * y;
    g.colwise() += x.colwise().squaredNorm().transpose();
    g.rowwise() += y.colwise().squaredNorm();
    d[k] = (g / nv).cwiseMax(0.0);
  });
  double d_max = 0;
  for (const Eigen::MatrixXd& m : d) d_max = std::max(d_max, m.maxCoeff());
  if (!(d_max > 0)) {
    throw InputError(fmt::format("similarity '{}' -> '{}': every pair of frames coincides",
                                 source.name, target.name));
  }
  EdgeSimilarity s;
  s.source_inputs = ns;
  s.target_inputs = nt;
  s.source_samples = fs;
  s.target_samples = ft;
  s.max_distance = d_max;
  s.values.resize(static_cast<std::size_t>(fs) * ft * ns * nt);
  for (int u = 0; u < fs; ++u) {
    for (int v = 0; v < ft; ++v) {
      for (int i = 0; i < ns; ++i) {
        for (int j = 0; j < nt; ++j) {
          s.values[((static_cast<std::size_t>(u) * ft + v) * ns + i) * nt + j] =
              static_cast<float>(std::clamp(1.0 - d[i * nt + j](u, v) / d_max, 0.0, 1.0));
        }
      }
    }
  }
  return s;
}

void reference_normals(const MotionSpace& space, AlignedFloats* normals,
                       AlignedHalfs* displacements) {
  const BlendSpace& b = space.blend;
  AlignedFloats all(static_cast<std::size_t>(b.num_references()) * b.num_frames * b.frame_stride(),
                    0.f);
  const int frames = b.num_references() * b.num_frames;
  const std::size_t stride = b.plane_stride;
  tbb::parallel_for(0, frames, [&](int k) {
    std::vector<float> x(b.frame_stride());
    reference_frame(b, k / b.num_frames, k % b.num_frames, x.data());
    float* n = all.data() + k * b.frame_stride();
    auto p = [&](int v) { return Eigen::Vector3f(x[v], x[stride + v], x[2 * stride + v]); };
    for (const Tri& t : space.triangles) {
      const Eigen::Vector3f fn = (p(t[1]) - p(t[0])).cross(p(t[2]) - p(t[0]));  // 2 x area
      for (int c = 0; c < 3; ++c) {
        n[t[c]] += fn.x();
        n[stride + t[c]] += fn.y();
        n[2 * stride + t[c]] += fn.z();
      }
    }
    for (int v = 0; v < b.num_vertices; ++v) {
      const float len = std::sqrt(n[v] * n[v] + n[stride + v] * n[stride + v] +
                                  n[2 * stride + v] * n[2 * stride + v]);
      if (len > 0) {
        n[v] /= len;
        n[stride + v] /= len;
        n[2 * stride + v] /= len;
      }
    }
  });
  split_reference_frames(b, all, normals, displacements);
}

}  // namespace fourd::graph
