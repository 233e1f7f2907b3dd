// Validation of the runtime (the paper's Figures 7 and 8c): the session's control scripts that
// follow a path (play/*.txt, runtime/player.h) are played on the pipeline asset (asset/) and
// the oracle asset (asset_oracle/) with the player library, and the root's distance from the
// path and the length it travelled are measured; a top-down plot shows the followed root over
// the requested path. A filmstrip shows one transition (a cyclic space to a one-shot space)
// every 5th frame at trellis depths 12, 10, 5 and 3, the meshes of the transition in pink and
// the source and target in yellow, as in the paper's Figure 7.
#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <opencv2/imgproc.hpp>

#include "pipeline/core/error.h"
#include "pipeline/core/image_io.h"
#include "pipeline/core/log.h"
#include "runtime/asset.h"
#include "runtime/character.h"
#include "runtime/player.h"
#include "stages/common/figure.h"
#include "stages/validate/validate.h"

namespace fourd::validate {
namespace {

namespace fs = std::filesystem;

constexpr const char* kAssetFile = "motion_graph.fourd";
constexpr double kPathTolerance = 0.25;  // [m] the corridor, drawn on the plot
constexpr int kFilmstripEvery = 5;       // frames between filmstrip panels
constexpr int kFilmstripDepths[] = {12, 10, 5, 3};

// BGR colour of motion space k in the plots.
cv::Scalar space_color(int k) {
  static const cv::Scalar palette[] = {{180, 110, 30}, {30, 120, 230}, {60, 160, 60},
                                       {40, 40, 200},  {160, 80, 150}, {120, 120, 120}};
  return palette[k % 6];
}

struct PathPlay {
  std::string script;  // file stem
  GroundPath path;
  PlayerReport report;
};

// Every script in play/ that follows a path, sorted by name. Scripts naming a space the asset
// lacks are left out, with the reason in `skipped`; a malformed script is an InputError.
std::vector<std::pair<std::string, ControlScript>> path_scripts(const fs::path& dir,
                                                                const MotionGraph& graph,
                                                                std::vector<std::string>* skipped) {
  std::vector<std::pair<std::string, ControlScript>> out;
  std::error_code ec;
  if (!fs::is_directory(dir, ec)) return out;
  std::vector<fs::path> files;
  for (const auto& e : fs::directory_iterator(dir)) {
    if (e.is_regular_file() && e.path().extension() == ".txt") files.push_back(e.path());
  }
  std::sort(files.begin(), files.end());
  for (const fs::path& file : files) {
    ControlScript script = read_control_script(file);
    if (script.path.empty()) continue;
    try {
      check_control_script(script, graph);
    } catch (const InputError& e) {
      skipped->push_back(e.what());
      continue;
    }
    out.emplace_back(file.stem().string(), std::move(script));
  }
  return out;
}

// Top-down plot: per script, the 0.25 m corridor around the requested path (grey), the path
// (dark; gaps red) and the root followed, coloured by motion space.
cv::Mat plot_paths(const std::vector<PathPlay>& plays, const MotionGraph& graph,
                   const std::string& title) {
  const int width = 960, margin = 40, header = 46;
  struct Box {
    double x0 = 1e300, y0 = 1e300, x1 = -1e300, y1 = -1e300;
    void add(double x, double y) {
      x0 = std::min(x0, x), y0 = std::min(y0, y), x1 = std::max(x1, x), y1 = std::max(y1, y);
    }
  };
  std::vector<Box> boxes(plays.size());
  double extent_x = 1;
  for (std::size_t i = 0; i < plays.size(); ++i) {
    const GroundPath& path = plays[i].path;
    for (double s = 0; s <= path.length(); s += 0.05) {
      const Point2 p = path.point_at(s);
      boxes[i].add(p.x, p.y);
    }
    for (const PlayedFrame& f : plays[i].report.played) boxes[i].add(f.x, f.y);
    boxes[i].x0 -= 0.5, boxes[i].x1 += 0.5, boxes[i].y0 -= 0.5, boxes[i].y1 += 0.5;
    extent_x = std::max(extent_x, boxes[i].x1 - boxes[i].x0);
  }
  const double scale = (width - 2 * margin) / extent_x;  // [px per m], one for every panel
  std::vector<int> heights;
  int total = header;
  for (const Box& b : boxes) {
    heights.push_back(static_cast<int>(std::ceil((b.y1 - b.y0) * scale)) + 2 * margin);
    total += heights.back();
  }
  cv::Mat image(total + 30, width, CV_8UC3, cv::Scalar(255, 255, 255));
  const int font = cv::FONT_HERSHEY_SIMPLEX;
  const cv::Scalar ink(30, 30, 30);
  cv::putText(image, title, cv::Point(10, 24), font, 0.6, ink, 1, cv::LINE_AA);
  int top = header;
  for (std::size_t i = 0; i < plays.size(); ++i) {
    const Box& b = boxes[i];
    const int h = heights[i];
    auto px = [&](double x, double y) {
      return cv::Point(static_cast<int>(std::lround(margin + (x - b.x0) * scale)),
                       static_cast<int>(std::lround(top + h - margin - (y - b.y0) * scale)));
    };
    // 1 m grid.
    for (double x = std::ceil(b.x0); x <= b.x1; x += 1) {
      cv::line(image, px(x, b.y0), px(x, b.y1), cv::Scalar(235, 235, 235), 1);
    }
    for (double y = std::ceil(b.y0); y <= b.y1; y += 1) {
      cv::line(image, px(b.x0, y), px(b.x1, y), cv::Scalar(235, 235, 235), 1);
    }
    const GroundPath& path = plays[i].path;
    const int corridor = std::max(1, static_cast<int>(std::lround(2 * kPathTolerance * scale)));
    std::vector<cv::Point> line;
    for (double s = 0;; s += 0.02) {
      const Point2 p = path.point_at(std::min(s, path.length()));
      line.push_back(px(p.x, p.y));
      if (s >= path.length()) break;
    }
    cv::polylines(image, line, false, cv::Scalar(215, 215, 215), corridor, cv::LINE_AA);
    cv::polylines(image, line, false, cv::Scalar(90, 90, 90), 1, cv::LINE_AA);
    for (int c = 0; c < static_cast<int>(path.curves().size()); ++c) {
      if (!path.curves()[c].gap) continue;
      std::vector<cv::Point> gap;
      for (double s = path.curve_start(c); s <= path.curve_end(c); s += 0.02) {
        const Point2 p = path.point_at(s);
        gap.push_back(px(p.x, p.y));
      }
      cv::polylines(image, gap, false, cv::Scalar(60, 60, 220), 3, cv::LINE_AA);
      // The gap's edges across the corridor, so the jump drawn over it leaves them visible.
      for (const double s : {path.curve_start(c), path.curve_end(c)}) {
        const Point2 p = path.point_at(s);
        const double h = path.heading_at(s), r = 1.5 * kPathTolerance;
        cv::line(image, px(p.x - r * std::sin(h), p.y + r * std::cos(h)),
                 px(p.x + r * std::sin(h), p.y - r * std::cos(h)), cv::Scalar(60, 60, 220), 2,
                 cv::LINE_AA);
      }
    }
    const std::vector<PlayedFrame>& played = plays[i].report.played;
    for (std::size_t f = 1; f < played.size(); ++f) {
      cv::line(image, px(played[f - 1].x, played[f - 1].y), px(played[f].x, played[f].y),
               space_color(played[f].space), 2, cv::LINE_AA);
    }
    if (!played.empty()) {
      cv::circle(image, px(played.front().x, played.front().y), 5, ink, 1, cv::LINE_AA);
    }
    const PlayerReport& r = plays[i].report;
    cv::putText(image,
                fmt::format("{}: covered {:.2f} m of the path, travelled {:.2f} m ({:+.2f} %), max "
                            "distance {:.3f} m, {} jump(s){}",
                            plays[i].script, r.covered, r.travelled, r.length_error_pct(),
                            r.max_path_error, r.jumps, r.path_done ? "" : ", NOT finished"),
                cv::Point(margin, top + 18), font, 0.45, ink, 1, cv::LINE_AA);
    top += h;
  }
  // Legend: the spaces' colours.
  int x = margin;
  const int y = total + 18;
  cv::putText(image, "root followed, by motion space:", cv::Point(x, y), font, 0.42, ink, 1,
              cv::LINE_AA);
  x += 250;
  for (int k = 0; k < static_cast<int>(graph.spaces.size()); ++k) {
    cv::line(image, cv::Point(x, y - 4), cv::Point(x + 24, y - 4), space_color(k), 3);
    cv::putText(image, graph.spaces[k].name(), cv::Point(x + 30, y), font, 0.42, ink, 1,
                cv::LINE_AA);
    x += 40 + 9 * static_cast<int>(graph.spaces[k].name().size());
  }
  cv::putText(image, "grey: 0.25 m either side of the path; red: gap and its edges", cv::Point(x + 10, y), font,
              0.42, ink, 1, cv::LINE_AA);
  return image;
}

// The edge the filmstrip shows: the first from a cyclic space to a one-shot one, else the
// first that is not a self-loop; -1 if none.
int filmstrip_edge(const MotionGraph& graph) {
  int fallback = -1;
  for (int e = 0; e < static_cast<int>(graph.edges.size()); ++e) {
    const GraphEdge& edge = graph.edges[e];
    if (edge.self_loop) continue;
    if (graph.spaces[edge.from].cyclic() && !graph.spaces[edge.to].cyclic()) return e;
    if (fallback < 0) fallback = e;
  }
  return fallback;
}

struct Filmstrip {
  std::vector<FigurePanel> panels;  // row-major, blank panels fill short rows
  std::vector<std::string> rows, columns;
  std::string caption;
};

// The same request at each depth of kFilmstripDepths: the source plays 0.5 s at 90 % of its
// range, then the target is requested at the middle of its range; frames at the capture rate
// from the request until 0.5 s after the requested state is reached.
Filmstrip make_filmstrip(const Asset& asset, int edge_index) {
  const MotionGraph& graph = asset.graph;
  const GraphEdge& edge = graph.edges[edge_index];
  const GraphSpace& from = graph.spaces[edge.from];
  const GraphSpace& to = graph.spaces[edge.to];
  const double p_from = from.parameter_min() + 0.9 * (from.parameter_max() - from.parameter_min());
  const double p_to = 0.5 * (to.parameter_min() + to.parameter_max());
  const double dt = 1.0 / graph.fps;
  const int request_frame = static_cast<int>(std::lround(0.5 * graph.fps));
  const cv::Vec3b yellow(60, 210, 240), pink(190, 120, 250);
  std::vector<std::vector<FigurePanel>> rows;
  Filmstrip film;
  std::vector<Vec3f> world;
  for (const int depth : kFilmstripDepths) {
    TransitionOptions options = asset.transitions;
    options.depth = depth;
    Character character(graph, options);
    character.reset(edge.from, p_from);
    std::vector<FigurePanel> row;
    double arrived = -1, latency = -1;
    for (int f = 0; f < static_cast<int>(10 * graph.fps); ++f) {
      if (f == request_frame) character.request_motion(edge.to, p_to);
      character.step(f == 0 ? 0.0 : dt);
      const TransitionRecord& r = character.last_transition();
      if (f > request_frame && r.arrive_time >= 0 && arrived < 0) {
        arrived = character.time();
        latency = r.arrive_time - r.request_time;
      }
      if (arrived >= 0 && character.time() > arrived + 0.5) break;
      if (f < request_frame || (f - request_frame) % kFilmstripEvery != 0) continue;
      const CharacterState& s = character.state();
      const bool transition = s.phase != PlayPhase::kFree || s.fading;
      // World orientation, but at the root's ground position: the view is oblique, so a
      // character walking away would drift on the screen.
      const CharacterFrame& frame = character.frame();
      character_world_positions(frame, &world);
      FigurePanel panel;
      panel.positions.resize(3, static_cast<Eigen::Index>(world.size()));
      for (std::size_t v = 0; v < world.size(); ++v) {
        panel.positions.col(static_cast<Eigen::Index>(v)) =
            world[v].cast<double>() - Eigen::Vector3d(frame.root.x, frame.root.y, 0);
      }
      panel.colors.assign(world.size(), transition ? pink : yellow);
      row.push_back(std::move(panel));
    }
    film.rows.push_back(latency >= 0 ? fmt::format("depth {}: {:.2f} s", depth, latency)
                                     : fmt::format("depth {}: no path", depth));
    rows.push_back(std::move(row));
  }
  std::size_t columns = 0;
  for (const auto& row : rows) columns = std::max(columns, row.size());
  for (std::size_t c = 0; c < columns; ++c) {
    film.columns.push_back(fmt::format("+{:.2f} s", c * kFilmstripEvery * dt));
  }
  for (auto& row : rows) {
    row.resize(columns);
    for (auto& panel : row) film.panels.push_back(std::move(panel));
  }
  film.caption = fmt::format(
      "{} at {:.2f} to {} at {:.2f}, requested at +0 s; every {}th frame at {:g} fps; pink: "
      "the transition path (source to its exit, target from its entry to the requested state, "
      "cross-fade), yellow: source and target; row labels give the latency",
      from.name(), p_from, to.name(), p_to, kFilmstripEvery, graph.fps);
  return film;
}

}  // namespace

StageReport validate_paths(const ValidationContext& ctx) {
  StageReport report;
  const std::vector<RunFolder> runs = run_folders(ctx.session, "asset", kAssetFile);
  if (runs.empty()) {
    report.summary = "Skipped: no asset/motion_graph.fourd.";
    return report;
  }
  report.present = true;
  const fs::path play_dir = ctx.session.dir("play");
  report.summary = fmt::format(
      "The runtime plays the asset. Paths: every control script with a path in play/ "
      "(runtime/player.h) is played by the player library with its path follower; the root's "
      "largest distance from the path and the length of its trajectory against the length of the "
      "path it covered (the path ends arrive_distance short of its end) are measured (goals: "
      "within {} m, length error within 2 %). The logs of each play are in "
      "reports/plays/. Filmstrip: one transition at several trellis depths (paper Figure 7).",
      kPathTolerance);
  for (const RunFolder& run : runs) {
    const Asset asset = load_asset(run.dir / kAssetFile);
    std::vector<std::string> skipped;
    const auto scripts = path_scripts(play_dir, asset.graph, &skipped);
    for (const std::string& s : skipped) report.details += fmt::format("Skipped: {}\n\n", s);
    std::vector<PathPlay> plays;
    std::string table = fmt::format(
        "**{}** asset:\n\n| script | path [m] | covered [m] | travelled [m] | length error [%] | "
        "max distance "
        "[m] | jumps | jump middle - gap middle [m] | turning requests | root rotation share | "
        "finished |\n|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---|\n",
        run.label);
    double worst_distance = 0, worst_length = 0;
    int finished = 0;
    for (const auto& [name, script] : scripts) {
      PlayerOptions options;
      options.out_dir = ctx.reports_dir / "plays" / fmt::format("{}_{}", run.label, name);
      options.write_meshes = false;
      PathPlay play{name, GroundPath(script.path), run_player(asset, script, options)};
      const PlayerReport& r = play.report;
      table += fmt::format(
          "| {} | {:.3f} | {:.3f} | {:.3f} | {:+.2f} | {:.3f} | {} | {} | {} | {:.2f} | {} |\n",
          name, r.path_length, r.covered, r.travelled, r.length_error_pct(), r.max_path_error,
          r.jumps, r.jumps > 0 ? fmt::format("{:+.3f}", r.max_abs_jump_offset) : "-",
          r.turning_requests, r.root_turn_share, r.path_done ? "yes" : "NO");
      report.metrics.push_back({name + "_max_error_m", r.max_path_error, run.input,
                                name + ": largest distance of the root from the path [m]"});
      report.metrics.push_back({name + "_length_error_pct", r.length_error_pct(), run.input,
                                name + ": (root's path length - path covered) / path covered [%]"});
      if (r.jumps > 0) {
        report.metrics.push_back({name + "_jump_offset_m", r.max_abs_jump_offset, run.input,
                                  name + ": root at the jump's middle minus the gap's middle [m]"});
      }
      worst_distance = std::max(worst_distance, r.max_path_error);
      if (std::abs(r.length_error_pct()) > std::abs(worst_length))
        worst_length = r.length_error_pct();
      finished += r.path_done ? 1 : 0;
      plays.push_back(std::move(play));
    }
    if (!plays.empty()) {
      report.details += table + "\n";
      report.metrics.push_back({"max_error_m", worst_distance, run.input,
                                "largest distance from the path over every script [m]"});
      report.metrics.push_back({"length_error_pct", worst_length, run.input,
                                "length error of largest magnitude over every script [%]"});
      report.metrics.push_back({"finished", static_cast<double>(finished), run.input,
                                fmt::format("paths followed to their end (of {})", plays.size())});
      Picture p;
      p.file = fmt::format("paths_{}.png", run.label);
      write_image_atomic(
          ctx.reports_dir / p.file,
          plot_paths(plays, asset.graph,
                     fmt::format("Paths followed on the {} asset (top view, metres)", run.label)));
      p.caption = fmt::format(
          "paths ({} asset): the root followed (coloured by motion space) "
          "over the requested path, top view",
          run.label);
      report.pictures.push_back(p);
    }
    const int edge = filmstrip_edge(asset.graph);
    if (edge >= 0) {
      const Filmstrip film = make_filmstrip(asset, edge);
      FigureLayout layout;
      layout.panel_width = 110;
      layout.panel_height = 190;
      layout.row_labels = film.rows;
      layout.column_labels = film.columns;
      layout.title = fmt::format("Transition filmstrip ({} asset)", run.label);
      layout.common_floor = true;
      Picture p;
      p.file = fmt::format("transition_filmstrip_{}.png", run.label);
      write_image_atomic(
          ctx.reports_dir / p.file,
          render_figure(film.panels, asset.graph.spaces.front().motion.triangles, layout));
      p.caption = fmt::format("transition ({} asset): {}", run.label, film.caption);
      report.pictures.push_back(p);
    }
  }
  if (!fs::is_directory(play_dir)) {
    report.summary += " No play/ folder in the session: no paths were played.";
  }
  return report;
}

}  // namespace fourd::validate
