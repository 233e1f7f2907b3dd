// The frame's tips as landmarks for a fit, and the limb starts that use them: the template's
// limbs turned about their joints towards the tips, or bent along the frame's surface.
#include "stages/align/registration_internal.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "pipeline/core/log.h"
#include "pipeline/geometry/geodesic.h"
#include "pipeline/geometry/measures.h"

namespace fourd::align {

using namespace detail;

namespace {

// The vertices whose distance `dist` (from a tip) is at most `length`: the tip's limb.
std::vector<int> within(const std::vector<double>& dist, double length) {
  std::vector<int> out;
  for (std::size_t v = 0; v < dist.size(); ++v) {
    if (dist[v] <= length) out.push_back(static_cast<int>(v));
  }
  return out;
}

// Where the limb of a tip attaches to the body: the centre of the surface at `length` (less
// `band`) of geodesic distance `dist` from the tip, over `positions`. A limb's root (hip,
// shoulder) hardly moves when it swings, so it tells the left limb from the right one when
// their tips have crossed (a running leg kicked back behind the other).
Vec3d limb_root(const std::vector<double>& dist, const std::vector<Vec3f>& positions, int tip,
                double length, double band) {
  Vec3d sum = Vec3d::Zero();
  int count = 0;
  for (std::size_t v = 0; v < dist.size(); ++v) {
    if (dist[v] >= length - band && dist[v] <= length) {
      sum += positions[v].cast<double>();
      ++count;
    }
  }
  return count > 0 ? Vec3d(sum / count) : Vec3d(positions[tip].cast<double>());
}

}  // namespace

namespace detail {

TipLandmarks tip_landmarks(const TemplateModel& model, const std::vector<Vec3f>& positions,
                           const SurfaceQuery& target, const RegistrationOptions& options) {
  const Extremities& tips = model.extremities;
  if (tips.vertices.empty()) return {};
  TipLandmarks out;
  Mesh& frame = out.frame;
  frame.positions = target.positions();
  frame.triangles = target.triangles();
  out.frame_rings = edge_neighbours(frame);
  const int centre = nearest_vertex(frame.positions, positions[tips.centre]);
  const Extremities frame_tips =
      find_extremities(frame, out.frame_rings, centre, options.extremities);
  const SurfaceQuery fitted_query(fitted_mesh(model, positions));

  // The limbs' roots, on the fit and on the frame (without limbs: the tips themselves).
  auto root_length = [&](double geodesic) { return options.limb_fraction * geodesic; };
  std::vector<Vec3d> template_root(tips.vertices.size()), frame_root(frame_tips.vertices.size());
  for (std::size_t i = 0; i < tips.vertices.size(); ++i) {
    template_root[i] = options.limb_fraction > 0
                           ? limb_root(model.tip_distance[i], positions, tips.vertices[i],
                                       root_length(tips.geodesic[i]), options.limb_band)
                           : Vec3d(positions[tips.vertices[i]].cast<double>());
  }
  for (std::size_t j = 0; j < frame_tips.vertices.size(); ++j) {
    const int tip = frame_tips.vertices[j];
    if (options.limb_fraction <= 0) {
      frame_root[j] = frame.positions[tip].cast<double>();
      continue;
    }
    const double length = root_length(frame_tips.geodesic[j]);
    std::vector<double> dist(frame.num_vertices(), std::numeric_limits<double>::infinity());
    std::vector<int> owner(frame.num_vertices(), -1);
    geodesic_update(frame, out.frame_rings, tip, 0, length, dist, owner);
    frame_root[j] = limb_root(dist, frame.positions, tip, length, options.limb_band);
  }

  std::vector<Vec3d> template_at;
  for (int v : tips.vertices) template_at.push_back(positions[v].cast<double>());
  std::vector<Landmark>& landmarks = out.landmarks;
  std::vector<int>& landmark_tips = out.frame_tips;
  std::vector<char> template_used(tips.vertices.size(), 0);
  Extremities missed;
  std::vector<Vec3d> missed_root;
  std::vector<Vec3d> missed_at;
  for (std::size_t j = 0; j < frame_tips.vertices.size(); ++j) {
    const Vec3f& p = frame.positions[frame_tips.vertices[j]];
    const bool covered =
        fitted_query.closest(p, static_cast<float>(options.coverage_distance)).found;
    const int anchor = anchored_tip(template_at, template_root, template_used, p.cast<double>(),
                                    frame_root[j], options.extremities.anchor_distance);
    if (covered && anchor >= 0) {
      template_used[anchor] = 1;
      landmarks.push_back({tips.vertices[anchor], p.cast<double>()});
      landmark_tips.push_back(frame_tips.vertices[j]);
    } else {
      missed.vertices.push_back(frame_tips.vertices[j]);
      missed.geodesic.push_back(frame_tips.geodesic[j]);
      missed_at.push_back(p.cast<double>());
      missed_root.push_back(frame_root[j]);
    }
  }
  if (missed.vertices.empty()) return out;
  // The missed tips are matched by where their limbs attach, not by where the tips are.
  Extremities free;
  std::vector<Vec3d> free_root;
  for (std::size_t i = 0; i < tips.vertices.size(); ++i) {
    if (template_used[i]) continue;
    free.vertices.push_back(tips.vertices[i]);
    free.geodesic.push_back(tips.geodesic[i]);
    free_root.push_back(template_root[i]);
  }
  const std::vector<TipMatch> matches =
      match_extremities(free, free_root, missed, missed_root, options.extremities);
  for (const TipMatch& m : matches) {
    landmarks.push_back({free.vertices[m.template_tip], missed_at[m.frame_tip]});
    landmark_tips.push_back(missed.vertices[m.frame_tip]);
  }
  log::debug("tips: {} in the frame, {} missed by the fit, {} of them matched; {} landmarks",
             frame_tips.vertices.size(), missed.vertices.size(), matches.size(), landmarks.size());
  out.missed = !matches.empty();
  return out;
}

}  // namespace detail

DeformationState turn_limbs_to_tips(const TemplateModel& model, const DeformationState& start,
                                    const std::vector<Landmark>& landmarks, double limb_fraction,
                                    double blend) {
  const Extremities& tips = model.extremities;
  const std::vector<Vec3f> at = deform_with_graph(model, start);
  DeformationState out = start;
  for (const Landmark& l : landmarks) {
    const auto tip = std::find(tips.vertices.begin(), tips.vertices.end(), l.vertex);
    if (tip == tips.vertices.end()) continue;
    const double length = limb_fraction * tips.geodesic[tip - tips.vertices.begin()];
    const std::vector<double>& dist = model.tip_distance[tip - tips.vertices.begin()];
    const std::vector<int> limb = within(dist, length);
    Vec3d joint = Vec3d::Zero();
    int border = 0;
    for (int v : limb) {
      for (int w : model.rings[v]) {
        if (dist[w] > length) {
          joint += at[v].cast<double>();
          ++border;
          break;
        }
      }
    }
    if (border == 0) continue;  // the whole template: not a limb
    joint /= border;
    const Vec3d from = at[l.vertex].cast<double>() - joint, to = l.point - joint;
    if (from.norm() < 1e-6 || to.norm() < 1e-6) continue;
    const Eigen::Quaterniond turn = Eigen::Quaterniond::FromTwoVectors(from, to);
    log::debug("limb of tip {}: {} vertices, {} on its border, turned {:.0f} deg", l.vertex,
               limb.size(), border, Eigen::AngleAxisd(turn).angle() * 180 / M_PI);
    const DeformationGraph& graph = model.graph;
    for (std::size_t k = 0; k < graph.node_vertex.size(); ++k) {
      const double d = dist[graph.node_vertex[k]];
      if (!(d <= length)) continue;
      const double w = blend > 0 ? std::clamp((length - d) / blend, 0.0, 1.0) : 1.0;
      const Mat3d r = Eigen::Quaterniond::Identity().slerp(w, turn).toRotationMatrix();
      // x -> r (y - joint) + joint after the node's own motion y = R (x - g) + g + t.
      const Vec3d& g = graph.node_position[k];
      out.rotation[k] = r * out.rotation[k];
      out.translation[k] = r * (g + out.translation[k] - joint) + joint - g;
    }
  }
  out.positions = deform_with_graph(model, out);
  return out;
}

DeformationState bend_limbs_along_frame(const TemplateModel& model, const DeformationState& start,
                                        const std::vector<Landmark>& landmarks,
                                        const std::vector<int>& frame_tips, const Mesh& frame,
                                        const std::vector<std::vector<int>>& frame_rings,
                                        double limb_fraction, double band) {
  const Extremities& tips = model.extremities;
  const std::vector<Vec3f> at = deform_with_graph(model, start);
  const double inf = std::numeric_limits<double>::infinity();
  DeformationState out = start;
  std::vector<double> frame_dist(frame.num_vertices(), inf);
  std::vector<int> frame_owner(frame.num_vertices(), -1);
  for (std::size_t l = 0; l < landmarks.size() && l < frame_tips.size(); ++l) {
    const auto tip = std::find(tips.vertices.begin(), tips.vertices.end(), landmarks[l].vertex);
    if (tip == tips.vertices.end()) continue;
    const double length = limb_fraction * tips.geodesic[tip - tips.vertices.begin()];
    const int bands = static_cast<int>(std::ceil(length / band));
    if (bands < 3) continue;
    const std::vector<double>& dist = model.tip_distance[tip - tips.vertices.begin()];
    const std::vector<int> limb = within(dist, length);
    const std::vector<int> reached = geodesic_update(frame, frame_rings, frame_tips[l], 0, length,
                                                     frame_dist, frame_owner);
    // The rings of equal geodesic distance from the tip, on the template and on the frame:
    // their centres are the limb's axis, whatever the limb's pose.
    struct Ring {
      Vec3d centre = Vec3d::Zero();
      double spread = 0;  // mean distance of its vertices from the centre
      int count = 0;
    };
    auto rings_of = [&](const std::vector<int>& vertices, const std::vector<double>& d,
                        auto position) {
      std::vector<Ring> r(bands);
      for (int v : vertices) {
        const int b = std::min(bands - 1, static_cast<int>(d[v] / band));
        r[b].centre += position(v);
        ++r[b].count;
      }
      for (Ring& x : r) {
        if (x.count > 0) x.centre /= x.count;
      }
      for (int v : vertices) {
        const int b = std::min(bands - 1, static_cast<int>(d[v] / band));
        r[b].spread += (position(v) - r[b].centre).norm() / r[b].count;
      }
      return r;
    };
    const std::vector<Ring> t_rings =
        rings_of(limb, dist, [&](int v) { return Vec3d(at[v].cast<double>()); });
    const std::vector<Ring> f_rings = rings_of(
        reached, frame_dist, [&](int v) { return Vec3d(frame.positions[v].cast<double>()); });
    for (int v : reached) frame_dist[v] = inf;
    // The limb is followed as far as the frame's rings look like the template's: a ring much
    // wider on the frame has run into the body (a hand resting on the hip).
    int valid = 0;
    while (valid < bands && t_rings[valid].count >= 3 && f_rings[valid].count >= 3 &&
           f_rings[valid].spread <= 1.5 * t_rings[valid].spread + 0.02) {
      ++valid;
    }
    if (valid < 3) continue;
    // Per ring: the turn of the limb's axis there and the move of its centre.
    std::vector<Mat3d> turn(valid);
    for (int b = 0; b < valid; ++b) {
      const int lo = std::max(0, b - 2), hi = std::min(valid - 1, b + 2);
      const Vec3d from = t_rings[hi].centre - t_rings[lo].centre;
      const Vec3d to = f_rings[hi].centre - f_rings[lo].centre;
      turn[b] = from.norm() > 1e-6 && to.norm() > 1e-6
                    ? Eigen::Quaterniond::FromTwoVectors(from, to).toRotationMatrix()
                    : Mat3d::Identity();
    }
    const double followed = std::min(length, valid * band);
    log::debug("limb of tip {}: followed along the frame over {:.2f} of {:.2f} m",
               landmarks[l].vertex, followed, length);
    const DeformationGraph& graph = model.graph;
    for (std::size_t k = 0; k < graph.node_vertex.size(); ++k) {
      const double d = dist[graph.node_vertex[k]];
      if (!(d <= length)) continue;
      const int b = std::min(valid - 1, static_cast<int>(d / band));
      // Beyond the followed part the last ring's motion fades out towards the limb's border.
      const double w = d < followed || length <= followed
                           ? 1.0
                           : std::clamp((length - d) / (length - followed), 0.0, 1.0);
      const Mat3d r = Eigen::Quaterniond::Identity()
                          .slerp(w, Eigen::Quaterniond(turn[b]))
                          .toRotationMatrix();
      const Vec3d shift = w * (f_rings[b].centre - t_rings[b].centre);
      // The node's moved position y = g + t turns about its ring's centre and moves with it.
      const Vec3d& g = graph.node_position[k];
      const Vec3d y = g + out.translation[k];
      out.rotation[k] = r * out.rotation[k];
      out.translation[k] = r * (y - t_rings[b].centre) + t_rings[b].centre + shift - g;
    }
  }
  out.positions = deform_with_graph(model, out);
  return out;
}

}  // namespace fourd::align
