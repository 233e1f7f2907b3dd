// The procedural performer: implicit body -> marching tetrahedra -> isotropic remeshing ->
// projection onto the implicit surface -> skinning weights, UVs, clothing texture.
#include <fmt/format.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <map>
#include <numeric>

#include "pipeline/core/error.h"
#include "pipeline/geometry/components.h"
#include "pipeline/geometry/measures.h"
#include "pipeline/geometry/remesh.h"
#include "stages/synth/body_model.h"
#include "stages/synth/character.h"
#include "stages/synth/clothing.h"
#include "stages/synth/garment.h"
#include "stages/synth/implicit_mesh.h"
#include "stages/synth/quadruped.h"

namespace fourd::synth {
namespace {

using detail::BodyModel;
using Eigen::Vector3d;

// Every edge used once in each direction: closed, manifold along edges, consistently oriented.
void require_closed_oriented(const Mesh& mesh) {
  std::map<std::pair<int, int>, int> directed;
  for (const Tri& t : mesh.triangles) {
    for (int c = 0; c < 3; ++c) ++directed[{t[c], t[(c + 1) % 3]}];
  }
  for (const auto& [edge, count] : directed) {
    auto reverse = directed.find({edge.second, edge.first});
    if (count != 1 || reverse == directed.end() || reverse->second != 1) {
      throw SolverError(fmt::format("procedural character: mesh edge ({}, {}) is not shared by exactly two "
                                    "consistently oriented triangles", edge.first, edge.second));
    }
  }
}

// Moves each vertex onto the zero set of the implicit body by Newton steps along the gradient.
void project_to_surface(const BodyModel& body, Mesh& mesh) {
  const double h = 1e-5;
  for (Vec3f& vertex : mesh.positions) {
    Vector3d p = vertex.cast<double>();
    for (int iteration = 0; iteration < 3; ++iteration) {
      const double f = body_field(body, p);
      Vector3d grad;
      for (int a = 0; a < 3; ++a) {
        Vector3d e = Vector3d::Zero();
        e[a] = h;
        grad[a] = (body_field(body, p + e) - body_field(body, p - e)) / (2 * h);
      }
      const double g2 = grad.squaredNorm();
      if (g2 < 1e-12) break;
      p -= f * grad / g2;
    }
    vertex = p.cast<float>();
  }
}

// Marching tetrahedra on a fine grid, then isotropic remeshing to the target vertex count: a
// closed surface has about 2 A / (sqrt(3) L^2) vertices for edge length L. A second, cheap
// pass on the result corrects the edge length by the measured count.
Mesh mesh_body(const BodyModel& body, int target_vertices) {
  const double spacing = 0.014 * body.scale;
  Vector3d lo, hi;
  body_bounds(body, 3 * spacing + 3 * body.blend_radius, &lo, &hi);
  const ScalarGrid grid = detail::sample_distance_field([&](const Vector3d& p) { return body_field(body, p); }, lo,
                                                       hi, spacing, 1.5);
  const Mesh dense = largest_component(extract_isosurface(grid));
  const double area = surface_area(dense);
  double edge = std::sqrt(2 * area / (std::sqrt(3.0) * target_vertices));
  Mesh mesh = remesh_isotropic(dense, edge, 2);
  edge *= std::sqrt(static_cast<double>(mesh.num_vertices()) / target_vertices);
  mesh = remesh_isotropic(mesh, edge, 3);
  project_to_surface(body, mesh);
  return mesh;
}

// The bones where the limbs join the trunk.
bool joins_trunk(const std::string& joint) {
  for (const char* prefix : {"pelvis", "spine", "chest", "clavicle", "upper_arm", "thigh"}) {
    if (joint.rfind(prefix, 0) == 0) return true;
  }
  return false;
}

// Dense #V x #joints skinning weights. A vertex belongs to the joints whose primitives it is
// close to: a softmax over the primitives' signed distances, options.skin_blend x the body's
// smooth-union radius wide (trunk_skin_blend for the bones that join the trunk), so weights
// blend where the implicit surface blends primitives (elbows, knees, shoulders, hips); then
// skin_smoothing rounds of averaging over the mesh soften the transitions.
Eigen::MatrixXd dense_weights(const BodyModel& body, const Mesh& mesh,
                              const CharacterOptions& options) {
  const std::size_t nv = mesh.num_vertices(), nj = body.skeleton.size();
  std::vector<double> sigma(nj);
  for (std::size_t j = 0; j < nj; ++j) {
    sigma[j] = (joins_trunk(body.skeleton.names[j]) ? options.trunk_skin_blend : options.skin_blend) *
               body.blend_radius;
  }
  Eigen::MatrixXd w = Eigen::MatrixXd::Zero(static_cast<Eigen::Index>(nv), static_cast<Eigen::Index>(nj));
  std::vector<double> d(body.primitives.size());
  for (std::size_t v = 0; v < nv; ++v) {
    primitive_distances(body, mesh.positions[v].cast<double>(), d.data());
    std::vector<double> joint_d(nj, std::numeric_limits<double>::infinity());
    for (std::size_t p = 0; p < d.size(); ++p) {
      double& jd = joint_d[static_cast<std::size_t>(body.primitives[p].joint)];
      jd = std::min(jd, d[p]);
    }
    const double dmin = *std::min_element(joint_d.begin(), joint_d.end());
    for (std::size_t j = 0; j < nj; ++j) {
      w(static_cast<Eigen::Index>(v), static_cast<Eigen::Index>(j)) = std::exp(-(joint_d[j] - dmin) / sigma[j]);
    }
    w.row(static_cast<Eigen::Index>(v)) /= w.row(static_cast<Eigen::Index>(v)).sum();
  }
  const auto adj = edge_neighbours(mesh);
  for (int round = 0; round < options.skin_smoothing; ++round) {
    Eigen::MatrixXd next = w;
    for (std::size_t v = 0; v < nv; ++v) {
      Eigen::RowVectorXd mean = Eigen::RowVectorXd::Zero(static_cast<Eigen::Index>(nj));
      for (int n : adj[v]) mean += w.row(n);
      mean /= static_cast<double>(adj[v].size());
      next.row(static_cast<Eigen::Index>(v)) = 0.5 * w.row(static_cast<Eigen::Index>(v)) + 0.5 * mean;
    }
    w = std::move(next);
  }
  return w;
}

// The four largest weights per vertex, renormalised so they sum to 1 in float arithmetic.
void pick_influences(const Eigen::MatrixXd& dense, SkinnedMesh& skin) {
  const auto nv = static_cast<std::size_t>(dense.rows());
  skin.joints.assign(nv, Eigen::Vector4i::Zero());
  skin.weights.assign(nv, Eigen::Vector4f::Zero());
  std::vector<int> order(static_cast<std::size_t>(dense.cols()));
  for (std::size_t v = 0; v < nv; ++v) {
    const auto row = dense.row(static_cast<Eigen::Index>(v));
    std::iota(order.begin(), order.end(), 0);
    std::stable_sort(order.begin(), order.end(), [&](int a, int b) { return row(a) > row(b); });
    double total = 0;
    for (int k = 0; k < 4; ++k) total += row(order[static_cast<std::size_t>(k)]);
    float rest = 1.0f;
    for (int k = 3; k >= 1; --k) {
      const double w = row(order[static_cast<std::size_t>(k)]) / total;
      const float wf = w < 1e-4 ? 0.0f : static_cast<float>(w);
      skin.weights[v][k] = wf;
      rest -= wf;
    }
    skin.weights[v][0] = rest;  // the largest takes the rounding, so the sum is exactly 1
    for (int k = 0; k < 4; ++k) skin.joints[v][k] = order[static_cast<std::size_t>(k)];
  }
}

// The chart of a vertex: the body part (torso, arm, leg, foot) carrying most of its weight.
std::vector<detail::ChartRef> vertex_charts(const BodyModel& body, const Eigen::MatrixXd& dense) {
  const Skeleton& sk = body.skeleton;
  std::vector<detail::ChartRef> part_of_joint(sk.size());
  for (std::size_t j = 0; j < sk.size(); ++j) {
    const std::string& n = sk.names[j];
    const int side = n.size() > 2 && n.substr(n.size() - 2) == "_r" ? 1 : 0;
    detail::Chart chart = detail::Chart::kTorso;
    if (n.rfind("upper_arm", 0) == 0 || n.rfind("forearm", 0) == 0 || n.rfind("hand", 0) == 0) {
      chart = detail::Chart::kArm;
    } else if (n.rfind("thigh", 0) == 0 || n.rfind("shin", 0) == 0) {
      chart = detail::Chart::kLeg;
    } else if (n.rfind("foot", 0) == 0 || n.rfind("toe", 0) == 0) {
      chart = detail::Chart::kFoot;
    }
    part_of_joint[j] = {chart, chart == detail::Chart::kTorso ? 0 : side};
  }
  auto key = [](const detail::ChartRef& r) { return static_cast<int>(r.chart) * 2 + r.side; };
  std::vector<detail::ChartRef> charts(static_cast<std::size_t>(dense.rows()));
  for (Eigen::Index v = 0; v < dense.rows(); ++v) {
    double part_weight[8] = {0};
    for (std::size_t j = 0; j < sk.size(); ++j) part_weight[key(part_of_joint[j])] += dense(v, static_cast<Eigen::Index>(j));
    const int best = static_cast<int>(std::max_element(part_weight, part_weight + 8) - part_weight);
    charts[static_cast<std::size_t>(v)] = {static_cast<detail::Chart>(best / 2), best % 2};
  }
  return charts;
}

}  // namespace

void CharacterOptions::check() const {
  if (body != "human" && body != "quadruped") {
    throw ConfigError(fmt::format("body '{}' is not one of human, quadruped", body));
  }
  if (garment != "none" && garment != "skirt") {
    throw ConfigError(fmt::format("garment '{}' is not one of none, skirt", garment));
  }
  if (body == "quadruped" && garment != "none") {
    throw ConfigError(fmt::format("garment '{}': the quadruped wears none", garment));
  }
  const double lo = body == "human" ? 1.2 : 0.3, hi = 2.2;
  if (!(height >= lo && height <= hi)) {
    throw ConfigError(fmt::format("height {} m: a {} is {} to {} m tall", height, body, lo, hi));
  }
}

Character make_procedural_character(const CharacterOptions& options, std::uint64_t seed,
                                    const std::optional<Eigen::Vector3d>& wardrobe_key) {
  options.check();
  if (options.target_vertices < 500 || options.texture_size < 16) {
    throw ConfigError(fmt::format("character: target_vertices {} / texture_size {} too small",
                                  options.target_vertices, options.texture_size));
  }
  const bool quadruped = options.body == "quadruped";
  const BodyModel body = quadruped ? detail::make_quadruped_model(options.height, options.build)
                                   : detail::make_body_model(options.height, options.build);
  Mesh mesh = mesh_body(body, options.target_vertices);
  require_closed_oriented(mesh);

  Character character;
  character.name = options.name;
  character.skeleton = body.skeleton;
  SkinnedMesh& skin = character.skin;

  const Eigen::MatrixXd dense = dense_weights(body, mesh, options);
  pick_influences(dense, skin);
  if (quadruped) {
    mesh.uvs = detail::quadruped_uvs(body, mesh, dense);
  } else {
    const auto charts = vertex_charts(body, dense);
    mesh.uvs.resize(mesh.num_vertices());
    for (std::size_t v = 0; v < mesh.num_vertices(); ++v) {
      mesh.uvs[v] = detail::chart_uv(body, charts[v], mesh.positions[v].cast<double>());
    }
  }
  mesh.texture = "texture.png";

  // Exact floor contact and height: shift the lowest point to z = 0, then scale about the
  // origin so that the top of the head is at the requested height. Skeleton moves along.
  float min_z = std::numeric_limits<float>::max(), max_z = std::numeric_limits<float>::lowest();
  for (const Vec3f& p : mesh.positions) {
    min_z = std::min(min_z, p.z());
    max_z = std::max(max_z, p.z());
  }
  const double factor = options.height / (static_cast<double>(max_z) - min_z);
  for (Vec3f& p : mesh.positions) {
    p = (Vector3d(p.x(), p.y(), static_cast<double>(p.z()) - min_z) * factor).cast<float>();
  }
  Skeleton& sk = character.skeleton;
  sk.rest_offsets[0].z() -= min_z;
  for (Vector3d& offset : sk.rest_offsets) offset *= factor;
  skin.rest = std::move(mesh);
  character.height = 0;
  for (const Vec3f& p : skin.rest.positions) character.height = std::max(character.height, static_cast<double>(p.z()));

  const auto rest = forward_kinematics(sk, rest_pose(sk));
  skin.inverse_bind.resize(rest.size());
  for (std::size_t j = 0; j < rest.size(); ++j) skin.inverse_bind[j] = rest[j].inverse();

  std::optional<detail::SkirtChart> chart;
  if (options.garment == "skirt") {
    character.garment = make_skirt(character, detail::moved_body(body, Vector3d(0, 0, -min_z), factor), options);
    chart = detail::SkirtChart{character.garment->waist_radius, character.garment->length, character.garment->flare};
  }
  character.texture = quadruped ? detail::paint_coat(body, options.texture_size, seed, wardrobe_key)
                                : detail::paint_clothing(body, options.texture_size, seed, wardrobe_key, chart);
  return character;
}

}  // namespace fourd::synth
