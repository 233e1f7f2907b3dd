// Validation of the align stage (align/ on pipeline inputs, align_oracle/ on oracle inputs).
//
// Correspondence error: every template vertex is bound to its closest ground-truth surface
// point at the root frame (triangle + barycentric coordinates on the ground-truth mesh of that
// frame); the ground truth's consistent topology carries that point to every other frame, and
// the error is its distance to the aligned vertex. Surface error: aligned vertices to the
// frame's input surface (what align was given). Flipped triangles: aligned triangles whose
// normal opposes the normal of the same triangle followed through the ground truth.
#include <fmt/format.h>
#include <fmt/ranges.h>
#include <tbb/parallel_for.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <functional>
#include <limits>
#include <map>
#include <memory>
#include <set>
#include <nlohmann/json.hpp>
#include <opencv2/imgproc.hpp>

#include "pipeline/core/error.h"
#include "pipeline/core/files.h"
#include "pipeline/core/image_io.h"
#include "pipeline/core/mesh_io.h"
#include "pipeline/core/config.h"  // kReferenceSubjectSize
#include "pipeline/core/statistics.h"
#include "pipeline/geometry/measures.h"
#include "pipeline/geometry/mesh_query.h"
#include "pipeline/geometry/surface_query.h"
#include "stages/validate/sampling.h"
#include "stages/validate/validate.h"
#include "stages/validate/validate_align.h"

namespace fourd::validate {
namespace {

namespace fs = std::filesystem;
using json = nlohmann::json;

struct FrameRef {
  std::string take;
  std::string file;  // "<frame>.ply"
};

std::vector<FrameRef> aligned_frames(const fs::path& dir) {
  std::vector<FrameRef> out;
  for (const auto& take : fs::directory_iterator(dir)) {
    const std::string name = take.path().filename().string();
    if (!take.is_directory() || name == "sequential" || name.front() == '.') continue;
    for (const auto& f : fs::directory_iterator(take.path())) {
      if (f.is_regular_file() && f.path().extension() == ".ply") {
        out.push_back({name, f.path().filename().string()});
      }
    }
  }
  std::sort(out.begin(), out.end(), [](const FrameRef& a, const FrameRef& b) {
    return std::tie(a.take, a.file) < std::tie(b.take, b.file);
  });
  if (out.empty()) throw InputError(fmt::format("{}: no aligned <take>/<frame>.ply", dir.string()));
  return out;
}

double rms(const std::vector<double>& v) {
  double s = 0;
  for (double x : v) s += x * x;
  return v.empty() ? 0.0 : std::sqrt(s / v.size());
}


Vec3f triangle_normal(const std::vector<Vec3f>& p, const Tri& t) {
  return (p[t[1]] - p[t[0]]).cross(p[t[2]] - p[t[0]]);
}

// Where a template vertex sits between two parts of the truth that touch at the root frame (an
// arm resting on the trunk, thighs pressed together), its closest truth point can be on the
// other part than its whole neighbourhood's; followed through the truth, that binding tears
// away (0.1-0.4 m in frames where the parts part) while the aligned surface there is right.
// A binding is torn when, in some truth frame of `frames`, its followed point lies more than
// kTornFactor x the template's edges there from its neighbours' (skin stretches by far less).
// A torn vertex is bound again to its closest point on the truth triangles its untorn
// neighbours are bound to and the triangles around them. Returns how many were.
constexpr double kTornFactor = 3;
int rebind_torn(const Mesh& templ, const Mesh& truth_root, const std::vector<Mesh>& frames,
                std::vector<int>& bound_triangle, std::vector<Vec3f>& bound_weights) {
  const std::vector<std::vector<int>> ring = edge_neighbours(templ);
  const std::size_t n = templ.num_vertices();
  std::vector<char> torn(n, 0);
  tbb::parallel_for(std::size_t{0}, n, [&](std::size_t v) {
    if (ring[v].empty()) return;
    std::vector<double> edges;
    for (int j : ring[v]) edges.push_back((templ.positions[v] - templ.positions[j]).norm());
    const double edge = median(edges);
    for (const Mesh& truth : frames) {
      const Vec3f at = barycentric_point(truth, bound_triangle[v], bound_weights[v]);
      std::vector<double> d;
      for (int j : ring[v]) d.push_back((at - barycentric_point(truth, bound_triangle[j], bound_weights[j])).norm());
      if (median(d) > kTornFactor * edge) {
        torn[v] = 1;
        return;
      }
    }
  });
  std::vector<std::vector<int>> triangles_of(truth_root.num_vertices());
  for (std::size_t t = 0; t < truth_root.triangles.size(); ++t) {
    for (int k : truth_root.triangles[t]) triangles_of[k].push_back(static_cast<int>(t));
  }
  int rebound = 0;
  for (std::size_t v = 0; v < n; ++v) {
    if (!torn[v]) continue;
    std::set<int> candidates;
    for (int j : ring[v]) {
      if (torn[j]) continue;
      for (int k : truth_root.triangles[bound_triangle[j]]) {
        candidates.insert(triangles_of[k].begin(), triangles_of[k].end());
      }
    }
    if (candidates.empty()) continue;
    double best = std::numeric_limits<double>::infinity();
    for (int t : candidates) {
      const Tri& tri = truth_root.triangles[t];
      Vec3f bary;
      const Vec3f q = closest_point_on_triangle(templ.positions[v], truth_root.positions[tri[0]],
                                                truth_root.positions[tri[1]], truth_root.positions[tri[2]], &bary);
      const double d = (q - templ.positions[v]).norm();
      if (d < best) {
        best = d;
        bound_triangle[v] = t;
        bound_weights[v] = bary;
      }
    }
    ++rebound;
  }
  return rebound;
}

}  // namespace

AlignmentErrors measure_alignment(const fs::path& align_dir, const fs::path& input_dir,
                                  const fs::path& truth_meshes, bool with_surface,
                                  const fs::path& frames_dir_arg) {
  const fs::path frames_dir = frames_dir_arg.empty() ? align_dir : frames_dir_arg;
  const json tree = json::parse(read_file(align_dir / "tree.json"));
  const json& root_node = tree.at("nodes").at(tree.at("root").get<std::size_t>());
  const std::string root_take = root_node.at("take").get<std::string>();
  const std::string root_file = frame_name(root_node.at("frame").get<int>()) + ".ply";
  const Mesh templ = read_ply(align_dir / "template.ply");
  const Mesh truth_root = read_ply(truth_meshes / root_take / root_file);

  // Bind the template to the ground truth at the root frame.
  AlignmentErrors out;
  out.root = root_take + "/" + root_node.at("frame").dump();
  out.triangles = templ.triangles;
  std::vector<int> bound_triangle(templ.num_vertices());
  std::vector<Vec3f> bound_weights(templ.num_vertices());
  {
    const MeshQuery query(truth_root);
    tbb::parallel_for(std::size_t{0}, templ.num_vertices(), [&](std::size_t i) {
      const ClosestPoint c = query.closest(templ.positions[i]);
      bound_triangle[i] = c.triangle;
      bound_weights[i] = c.barycentric;
    });
  }

  const std::vector<FrameRef> frames = aligned_frames(frames_dir);
  {
    // Up to 24 truth frames spread over the aligned ones show which bindings tear.
    std::vector<Mesh> sample;
    const std::size_t count = std::min<std::size_t>(24, frames.size());
    for (std::size_t i = 0; i < count; ++i) {
      const FrameRef& f = frames[i * frames.size() / count];
      sample.push_back(read_ply(truth_meshes / f.take / f.file));
      if (sample.back().triangles != truth_root.triangles) sample.pop_back();  // refused below
    }
    out.rebound = rebind_torn(templ, truth_root, sample, bound_triangle, bound_weights);
  }
  out.frames.resize(frames.size());
  tbb::parallel_for(std::size_t{0}, frames.size(), [&](std::size_t k) {
    const FrameRef& f = frames[k];
    AlignedFrameError& e = out.frames[k];
    e.take = f.take;
    e.frame = std::stoi(fs::path(f.file).stem().string());
    const Mesh aligned = read_ply(frames_dir / f.take / f.file);
    const Mesh truth = read_ply(truth_meshes / f.take / f.file);
    if (aligned.num_vertices() != templ.num_vertices()) {
      throw InputError(fmt::format("{}: {} vertices, the template has {}",
                                   (frames_dir / f.take / f.file).string(), aligned.num_vertices(),
                                   templ.num_vertices()));
    }
    if (truth.triangles != truth_root.triangles) {
      throw InputError(fmt::format("{}: ground truth topology differs from the root frame's",
                                   (truth_meshes / f.take / f.file).string()));
    }
    std::vector<Vec3f> followed(aligned.num_vertices());
    e.correspondence.resize(aligned.num_vertices());
    for (std::size_t i = 0; i < aligned.num_vertices(); ++i) {
      followed[i] = barycentric_point(truth, bound_triangle[i], bound_weights[i]);
      e.correspondence[i] = (aligned.positions[i] - followed[i]).norm();
    }
    for (std::size_t t = 0; t < templ.triangles.size(); ++t) {
      const Tri& tri = templ.triangles[t];
      if (triangle_normal(aligned.positions, tri).dot(triangle_normal(followed, tri)) <= 0) {
        e.flipped.push_back(static_cast<int>(t));
      }
    }
    if (with_surface) {
      const Mesh input = read_ply(input_dir / f.take / f.file);
      const MeshQuery query(input);
      e.surface.resize(aligned.num_vertices());
      for (std::size_t i = 0; i < aligned.num_vertices(); ++i) {
        e.surface[i] = query.distance(aligned.positions[i]);
      }
    }
  });
  return out;
}

void AlignmentErrors::summarise() {
  std::vector<double> all_corr, all_surface;
  std::set<int> distinct;
  std::vector<double> flip_errors;
  for (const AlignedFrameError& f : frames) {
    all_corr.insert(all_corr.end(), f.correspondence.begin(), f.correspondence.end());
    all_surface.insert(all_surface.end(), f.surface.begin(), f.surface.end());
    for (int t : f.flipped) {
      distinct.insert(t);
      const Tri& tri = triangles[t];
      flip_errors.push_back(std::max({f.correspondence[tri[0]], f.correspondence[tri[1]],
                                      f.correspondence[tri[2]]}));
    }
  }
  flipped = static_cast<int>(flip_errors.size());
  flipped_distinct = static_cast<int>(distinct.size());
  flipped_error_median = flip_errors.empty() ? 0.0 : percentile(flip_errors, 0.5);
  correspondence_rms = rms(all_corr);
  correspondence_p95 = percentile(all_corr, 0.95);
  surface_rms = rms(all_surface);
}

namespace {

// Per-frame correspondence rms against the frame's position in the take order (takes one
// after the other): tree in blue, the sequential baseline in red.
cv::Mat plot_errors(const AlignmentErrors& tree, const AlignmentErrors* sequential,
                    const std::string& title) {
  const int width = 900, height = 372, left = 60, right = 20, top = 40, bottom = 62;
  cv::Mat img(height, width, CV_8UC3, cv::Scalar(255, 255, 255));
  // x positions: frames of every take in order, a gap of 2 between takes.
  std::map<std::pair<std::string, int>, double> x_of;
  std::vector<std::pair<double, std::string>> take_starts;
  double x = 0;
  std::string last;
  auto place = [&](const AlignmentErrors& e) {
    for (const auto& f : e.frames) {
      if (x_of.count({f.take, f.frame})) continue;
      if (f.take != last) {
        if (!last.empty()) x += 2;
        take_starts.emplace_back(x, f.take);
        last = f.take;
      }
      x_of[{f.take, f.frame}] = x;
      x += 1;
    }
  };
  place(tree);
  if (sequential) place(*sequential);
  const double x_max = std::max(1.0, x - 1);
  double y_max = 1;
  auto frame_rms = [](const AlignedFrameError& f) { return 1e3 * rms(f.correspondence); };
  for (const auto& f : tree.frames) y_max = std::max(y_max, frame_rms(f));
  if (sequential) for (const auto& f : sequential->frames) y_max = std::max(y_max, frame_rms(f));
  y_max *= 1.1;
  auto px = [&](double fx, double fy) {
    return cv::Point(left + static_cast<int>(std::lround(fx / x_max * (width - left - right))),
                     height - bottom - static_cast<int>(std::lround(fy / y_max * (height - top - bottom))));
  };
  cv::rectangle(img, px(0, 0), px(x_max, y_max), {0, 0, 0}, 1);
  for (int i = 0; i <= 4; ++i) {
    const double v = y_max * i / 4;
    cv::line(img, px(0, v), px(x_max, v), {220, 220, 220}, 1);
    cv::putText(img, fmt::format("{:.0f}", v), px(0, v) + cv::Point(-45, 4), cv::FONT_HERSHEY_SIMPLEX,
                0.4, {0, 0, 0}, 1, cv::LINE_AA);
  }
  // Take names under the axis, on a second row where a short take would run into its
  // neighbour's.
  int row_end[2] = {std::numeric_limits<int>::min(), std::numeric_limits<int>::min()};
  for (const auto& [sx, name] : take_starts) {
    cv::line(img, px(sx, 0), px(sx, y_max), {180, 180, 180}, 1);
    const cv::Point at = px(sx, 0) + cv::Point(2, 0);
    const int text_width =
        cv::getTextSize(name, cv::FONT_HERSHEY_SIMPLEX, 0.4, 1, nullptr).width;
    const int row = at.x > row_end[0] ? 0 : 1;
    row_end[row] = at.x + text_width + 6;
    cv::putText(img, name, at + cv::Point(0, 15 + 13 * row), cv::FONT_HERSHEY_SIMPLEX, 0.4,
                {0, 0, 0}, 1, cv::LINE_AA);
  }
  auto draw = [&](const AlignmentErrors& e, const cv::Scalar& colour) {
    std::string take;
    cv::Point previous;
    for (const auto& f : e.frames) {
      const cv::Point p = px(x_of[{f.take, f.frame}], frame_rms(f));
      if (f.take == take) cv::line(img, previous, p, colour, 2, cv::LINE_AA);
      cv::circle(img, p, 2, colour, cv::FILLED, cv::LINE_AA);
      previous = p;
      take = f.take;
    }
  };
  if (sequential) draw(*sequential, {40, 40, 220});
  draw(tree, {200, 90, 20});
  cv::putText(img, title, {left, 25}, cv::FONT_HERSHEY_SIMPLEX, 0.5, {0, 0, 0}, 1, cv::LINE_AA);
  cv::putText(img, "tree", {width - 200, 25}, cv::FONT_HERSHEY_SIMPLEX, 0.5, {200, 90, 20}, 2,
              cv::LINE_AA);
  if (sequential) {
    cv::putText(img, "sequential", {width - 140, 25}, cv::FONT_HERSHEY_SIMPLEX, 0.5, {40, 40, 220},
                2, cv::LINE_AA);
  }
  cv::putText(img, "frame (takes in order)   /   correspondence rms [mm]", {left, height - 15},
              cv::FONT_HERSHEY_SIMPLEX, 0.45, {0, 0, 0}, 1, cv::LINE_AA);
  return img;
}

std::string take_table(const AlignmentErrors& e, const AlignmentErrors* sequential) {
  std::map<std::string, std::vector<double>> tree_corr, seq_corr;
  for (const auto& f : e.frames) {
    auto& v = tree_corr[f.take];
    v.insert(v.end(), f.correspondence.begin(), f.correspondence.end());
  }
  if (sequential) {
    for (const auto& f : sequential->frames) {
      auto& v = seq_corr[f.take];
      v.insert(v.end(), f.correspondence.begin(), f.correspondence.end());
    }
  }
  std::string md = "| take | correspondence rms [mm] | p95 [mm] | sequential rms [mm] |\n|---|---:|---:|---:|\n";
  for (const auto& [take, v] : tree_corr) {
    md += fmt::format("| {} | {:.2f} | {:.2f} | {} |\n", take, 1e3 * rms(v), 1e3 * percentile(v, 0.95),
                      seq_corr.count(take) ? fmt::format("{:.2f}", 1e3 * rms(seq_corr[take])) : "-");
  }
  return md;
}

// The frames with the largest correspondence error, worst first, as a markdown list (where to
// look first when the totals are off).
std::string worst_frames(const AlignmentErrors& e, std::size_t count) {
  std::vector<std::pair<double, const AlignedFrameError*>> order;
  for (const auto& f : e.frames) order.emplace_back(rms(f.correspondence), &f);
  std::sort(order.begin(), order.end(), [](const auto& a, const auto& b) { return a.first > b.first; });
  order.resize(std::min(order.size(), count));
  std::string md = "Worst frames (correspondence rms, surface rms, flipped triangles):\n\n";
  for (const auto& [value, f] : order) {
    md += fmt::format("- {}/{}: {:.1f} mm, {:.1f} mm, {}\n", f->take, f->frame, 1e3 * value,
                      1e3 * rms(f->surface), f->flipped.size());
  }
  return md + "\n";
}

// What align's self-diagnosis said of each frame against what it is: frames whose worst
// template vertex is more than `bad` off (truth) vs the frames align flagged `diagnosed_wrong`
// (report.json); precision counts a flag as right when the frame is more than `off` off
// somewhere. Adds the metrics and a confusion table, writes <reports>/<folder>_frames.json.
void diagnosis_confusion(const AlignmentErrors& errors, const json& align_report, double bad,
                         double off, const std::string& folder, const fs::path& reports_dir,
                         const std::function<void(const char*, double, const char*)>& add,
                         std::string* details) {
  std::map<std::pair<std::string, int>, const json*> entry_of;
  if (align_report.contains("per_frame")) {
    for (const json& e : align_report["per_frame"]) {
      entry_of[{e.value("take", ""), e.value("frame", -1)}] = &e;
    }
  }
  int counts[3][2] = {};  // [over bad | over off | within off][flagged]
  json frames = json::array();
  for (const AlignedFrameError& f : errors.frames) {
    const double worst = f.correspondence.empty()
                             ? 0.0
                             : *std::max_element(f.correspondence.begin(), f.correspondence.end());
    bool flagged = false;
    json wrong = json::array();
    const auto it = entry_of.find({f.take, f.frame});
    if (it != entry_of.end()) {
      const json& flags = it->second->value("flags", json::array());
      flagged = std::find(flags.begin(), flags.end(), "diagnosed_wrong") != flags.end();
      if (it->second->contains("diagnosis")) wrong = (*it->second)["diagnosis"].value("wrong", json::array());
    }
    const int row = worst > bad ? 0 : worst > off ? 1 : 2;
    ++counts[row][flagged ? 1 : 0];
    frames.push_back({{"take", f.take}, {"frame", f.frame}, {"rms_mm", 1e3 * rms(f.correspondence)},
                      {"worst_mm", 1e3 * worst}, {"flagged", flagged}, {"wrong", wrong}});
  }
  write_file_atomic(reports_dir / (folder + "_frames.json"), frames.dump(1) + "\n");
  const int truly_bad = counts[0][0] + counts[0][1];
  const int flagged = counts[0][1] + counts[1][1] + counts[2][1];
  add("frames_worst_over_50mm", truly_bad,
      "frames with a template vertex more than 50 mm (x the subject's size / 1.75 m) from its true place");
  add("diagnosed_wrong_frames", flagged, "frames align's self-diagnosis flagged (diagnosed_wrong)");
  if (truly_bad > 0) {
    add("diagnosis_recall", static_cast<double>(counts[0][1]) / truly_bad,
        "of the frames more than 50 mm off somewhere, the fraction align flagged");
  }
  if (flagged > 0) {
    add("diagnosis_precision", static_cast<double>(counts[0][1] + counts[1][1]) / flagged,
        "of the frames align flagged, the fraction more than 30 mm off somewhere");
  }
  *details += fmt::format(
      "Self-diagnosis against the truth (worst template vertex of each frame; {}_frames.json "
      "lists every frame):\n\n| worst vertex off by | flagged | not flagged |\n|---|---:|---:|\n"
      "| > {:.0f} mm | {} | {} |\n| {:.0f}-{:.0f} mm | {} | {} |\n| <= {:.0f} mm | {} | {} |\n\n",
      folder, 1e3 * bad, counts[0][1], counts[0][0], 1e3 * off, 1e3 * bad, counts[1][1],
      counts[1][0], 1e3 * off, counts[2][1], counts[2][0]);
}

}  // namespace

StageReport validate_align(const ValidationContext& ctx) {
  const Session& session = ctx.session;
  StageReport report;
  report.stage = "align";
  const fs::path truth_meshes = session.ground_truth_dir() / "meshes";
  struct Variant {
    const char* folder;
    InputKind input;
    fs::path input_dir;
  };
  std::error_code ec;
  const fs::path oracle_input = fs::is_directory(session.dir("reconstruct_oracle"), ec)
                                    ? session.dir("reconstruct_oracle")
                                    : session.dir("oracle") / "reconstruct";
  const Variant variants[] = {{"align", InputKind::kPipeline, session.dir("reconstruct")},
                              {"align_oracle", InputKind::kOracle, oracle_input}};
  std::vector<std::string> checked;
  for (const Variant& v : variants) {
    const fs::path dir = session.dir(v.folder);
    if (!fs::exists(dir / "tree.json", ec)) continue;
    if (!fs::is_directory(truth_meshes, ec)) {
      report.summary = "Skipped: no ground_truth/meshes (not a synthetic session).";
      return report;
    }
    report.present = true;
    AlignmentErrors errors = measure_alignment(dir, v.input_dir, truth_meshes, true);
    errors.summarise();
    std::unique_ptr<AlignmentErrors> sequential;
    if (fs::is_directory(dir / "sequential", ec)) {
      sequential = std::make_unique<AlignmentErrors>(
          measure_alignment(dir, v.input_dir, truth_meshes, false, dir / "sequential"));
      sequential->summarise();
    }
    double seconds_per_frame = 0;
    const json align_report = json::parse(read_file(dir / "report.json"));
    seconds_per_frame = align_report.value("seconds_per_frame", 0.0);
    auto add = [&](const char* name, double value, const char* meaning) {
      report.metrics.push_back({name, value, v.input, meaning});
    };
    add("correspondence_rms_mm", 1e3 * errors.correspondence_rms,
        "template vertices vs their ground-truth point followed from the root frame, rms over "
        "all frames");
    add("correspondence_p95_mm", 1e3 * errors.correspondence_p95, "... 95th percentile");
    add("surface_rms_mm", 1e3 * errors.surface_rms,
        "aligned vertices to the frame's input surface, rms");
    add("flipped_triangles", errors.flipped,
        "aligned triangles facing opposite to the same triangle followed through the ground truth");
    add("seconds_per_frame", seconds_per_frame, "align wall time per frame (align's report.json)");
    if (sequential) {
      add("sequential_correspondence_rms_mm", 1e3 * sequential->correspondence_rms,
          "the same for the sequential (frame-to-frame) baseline");
    }
    report.details += fmt::format("**{}** (root {}, {} frames):\n\n{}\n", v.folder, errors.root,
                                  errors.frames.size(), take_table(errors, sequential.get()));
    if (errors.rebound > 0) {
      report.details += fmt::format(
          "{} template vertices were bound to the truth on their neighbours' part: their closest "
          "truth point at the root was on a part touching it there.\n\n",
          errors.rebound);
    }
    report.details += worst_frames(errors, 8);
    {
      // 50 and 30 mm at the reference subject's size, scaled to this template's.
      const Mesh templ = read_ply(dir / "template.ply");
      Vec3f lo, hi;
      bounding_box(templ, &lo, &hi);
      const double scale = templ.positions.empty() ? 1.0 : (hi - lo).maxCoeff() / kReferenceSubjectSize;
      diagnosis_confusion(errors, align_report, 0.05 * scale, 0.03 * scale, v.folder,
                          ctx.reports_dir, add, &report.details);
    }
    if (errors.flipped > 0) {
      report.details += fmt::format(
          "Flipped triangles: {} over {} template triangles; the largest correspondence error of "
          "a flipped triangle's vertices, median {:.1f} mm (tens of mm: the surface slid along "
          "itself, e.g. across a crease; a few mm: folds).\n\n",
          errors.flipped, errors.flipped_distinct, 1e3 * errors.flipped_error_median);
    }
    Picture p;
    p.file = fmt::format("{}_correspondence.png", v.folder);
    write_image_atomic(ctx.reports_dir / p.file,
                       plot_errors(errors, sequential.get(),
                                   fmt::format("{}: correspondence error per frame", v.folder)));
    p.caption = fmt::format(
        "{}: correspondence rms per frame [mm], tree{}; takes one after the other", v.folder,
        sequential ? " (blue) vs sequential baseline (red)"
                   : " (no sequential baseline: set stages.align.sequential_baseline)");
    report.pictures.push_back(p);
    checked.push_back(v.folder);
  }
  if (!report.present) {
    report.summary = "Skipped: no align/tree.json or align_oracle/tree.json.";
    return report;
  }
  report.summary = fmt::format("Measured {} against ground_truth/meshes.",
                               fmt::format("{}", fmt::join(checked, " and ")));
  return report;
}

}  // namespace fourd::validate
