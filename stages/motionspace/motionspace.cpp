#include "stages/motionspace/motionspace.h"

#include <fmt/format.h>

#include <algorithm>
#include <nlohmann/json.hpp>

#include "pipeline/core/error.h"
#include "pipeline/core/files.h"
#include "pipeline/core/image_io.h"
#include "pipeline/core/log.h"
#include "pipeline/core/staged_folder.h"
#include "pipeline/core/subject.h"
#include "pipeline/exchange/aligned_input.h"
#include "pipeline/exchange/warped_class.h"
#include "stages/motionspace/table1.h"

namespace fourd::motionspace {

namespace {

nlohmann::json class_summary(const MotionSpace& space, const MotionSpaceReport& r,
                             const MotionspaceOptions& options, double seconds) {
  const ParameterMap& map = space.parameter_map;
  nlohmann::json checks = nlohmann::json::array();
  for (std::size_t i = 0; i < r.accuracy.requested.size(); ++i) {
    checks.push_back({{"requested", r.accuracy.requested[i]}, {"measured", r.accuracy.measured[i]}});
  }
  return {{"class", space.name},
          {"takes", space.takes},
          {"cyclic", space.cyclic},
          {"samples", space.num_samples()},
          {"vertices", space.blend.num_vertices},
          {"character_height_m", space.character_height},
          {"epsilon_m", options.epsilon},
          {"references_added", r.hybrid.references_added},
          {"cells", r.hybrid.cells},
          {"max_depth", r.hybrid.max_depth},
          {"converged", r.hybrid.converged},
          {"hybrid_max_error_m", r.hybrid.max_error},
          {"linear_max_error_m", r.hybrid.linear_max_error},
          {"nonlinear_solves", r.hybrid.nonlinear_solves},
          {"parameter", map.parameter},
          {"unit", map.unit},
          {"range", {map.min_value(), map.max_value()}},
          {"input_values", r.parameters.input_values},
          {"parameter_map_samples", map.values.size()},
          {"parameter_map_dropped", r.parameters.dropped_samples},
          {"parameter_error_max_pct", r.accuracy.max_error_pct},
          {"parameter_error_mean_pct", r.accuracy.mean_error_pct},
          {"parameter_checks", checks},
          {"build_seconds", seconds}};
}

std::filesystem::path class_file(const std::filesystem::path& dir, const std::string& name) {
  const std::filesystem::path path = dir / (name + ".twarp");
  if (!std::filesystem::exists(path)) {
    throw InputError(fmt::format("motion class {}: {} is missing (run fourd-timewarp first)", name,
                                 path.string()));
  }
  return path;
}

}  // namespace

void MotionspaceOptions::check() const { hybrid().check(); }

MotionSpace build_motion_space(const WarpedClass& c, const MotionspaceOptions& options,
                               MotionSpaceReport* report) {
  options.check();
  const int n = static_cast<int>(c.takes.size());
  if (n < 1 || n > 3) {
    throw InputError(fmt::format("motion class {}: {} takes (1 to 3 supported)", c.name, n));
  }
  MotionSpace space;
  space.name = c.name;
  space.cyclic = c.cyclic;
  space.character_height = c.character_height;
  space.triangles = c.triangles;
  space.blend = make_blend_space(n, c.num_vertices, c.num_samples);
  for (int k = 0; k < n; ++k) {
    const WarpedTake& t = c.takes[k];
    space.takes.push_back(t.name);
    for (int i = 0; i < c.num_samples; ++i) {
      const Vec3f* p = t.shapes.data() + static_cast<std::size_t>(i) * c.num_vertices;
      set_frame(&space.blend, k, i, std::span<const Vec3f>(p, c.num_vertices));
      space.roots.push_back({static_cast<float>(t.roots[i].x), static_cast<float>(t.roots[i].y),
                             static_cast<float>(t.roots[i].heading)});
      space.seconds.push_back(static_cast<float>(t.seconds[i]));
    }
  }
  report->hybrid = build_hybrid_references(options.hybrid(), c.template_positions, c.triangles,
                                           &space.blend);
  const ParameterProbe probe =
      make_parameter_probe(c.name, c.parameter, c.template_positions, space);
  space.parameter_map =
      build_parameter_map(probe, space, options.parameter_samples, &report->parameters);
  report->accuracy = check_parameter_accuracy(probe, space, options.parameter_checks);
  space.check();
  return space;
}

void run_motionspace(const Session& session, const StageArgs& args) {
  // epsilon scales to reconstruct's subject, or to the template's size when align/ was imported.
  const Subject subject = stage_subject(session, session.dir("reconstruct"), [&] {
    const std::filesystem::path align = stage_input_dir(session, args, "align");
    return measure_subject({open_aligned_input(align).template_mesh}, align.string());
  });
  MotionspaceOptions options;
  subject_stage_options(session, "motionspace", subject, options);
  const SessionConfig& config = session.config();
  if (config.motions.empty()) {
    throw InputError(fmt::format("{}: no motion classes declared (motions:)",
                                 session.config_path().string()));
  }
  // The timewarp stage's output in the same mode (timewarp_oracle/ when --oracle).
  const std::filesystem::path in = stage_output_dir(session, args, "timewarp");
  const std::filesystem::path out = stage_output_dir(session, args, "motionspace");
  for (const MotionClassConfig& m : config.motions) class_file(in, m.name);

  // Table 1 runs on the pair of takes whose shapes differ most in rotation, over all classes.
  std::string table_class;
  RotationScore table_pair;
  if (options.table1) {
    table_pair.mean_rotation_deg = -1;
    for (const MotionClassConfig& m : config.motions) {
      const WarpedClass c = read_warped_class(class_file(in, m.name));
      if (c.takes.size() < 2) continue;
      const RotationScore s = most_rotated_pair(c);
      log::info("{}: {} / {} differ most in rotation ({:.1f} deg mean per triangle)", m.name,
                c.takes[s.a].name, c.takes[s.b].name, s.mean_rotation_deg);
      if (s.mean_rotation_deg > table_pair.mean_rotation_deg) {
        table_pair = s;
        table_class = m.name;
      }
    }
  }

  StagedFolder staged(out);
  nlohmann::json summary = {{"classes", nlohmann::json::array()}};
  double parameter_error = 0;
  for (const MotionClassConfig& m : config.motions) {
    log::Timer timer;
    const WarpedClass c = read_warped_class(class_file(in, m.name));
    MotionSpaceReport report;
    const MotionSpace space = build_motion_space(c, options, &report);
    save_motion_space(staged.path() / (m.name + ".mspace"), space);
    const nlohmann::json js = class_summary(space, report, options, timer.seconds());
    write_file_atomic(staged.path() / (m.name + ".json"), js.dump(1));
    summary["classes"].push_back({{"class", m.name},
                                  {"parameter_error_max_pct", report.accuracy.max_error_pct},
                                  {"hybrid_max_error_m", report.hybrid.max_error},
                                  {"references_added", report.hybrid.references_added}});
    parameter_error = std::max(parameter_error, report.accuracy.max_error_pct);
    const ParameterMap& map = space.parameter_map;
    log::info("{}: {} references added, hybrid within {:.2f} mm of non-linear (linear {:.1f} mm); "
              "{} {:.3f} to {:.3f} {}, accuracy {:.3f} % of the range ({:.1f} s)",
              m.name, report.hybrid.references_added, 1000 * report.hybrid.max_error,
              1000 * report.hybrid.linear_max_error, map.parameter, map.min_value(),
              map.max_value(), map.unit, report.accuracy.max_error_pct, timer.seconds());
    if (!report.hybrid.converged) {
      log::warn("{}: the hybrid blend stays {:.2f} mm from the non-linear blend, above epsilon "
                "{:.2f} mm: raise stages.motionspace.max_references or max_depth",
                m.name, 1000 * report.hybrid.max_error, 1000 * options.epsilon);
    }
    if (report.parameters.dropped_samples > 0) {
      log::warn("{}: {} parameter samples were not monotone and were left out", m.name,
                report.parameters.dropped_samples);
    }
    if (m.name == table_class) {
      log::Timer table_timer;
      Table1 table = evaluate_table1(c, table_pair.a, table_pair.b, options.table1_weights);
      table.rotation_deg = table_pair.mean_rotation_deg;
      write_file_atomic(staged.path() / "table1.json", table1_json(table).dump(1));
      write_image_atomic(staged.path() / "figure4.png", table.figure);
      summary["table1"] = table1_json(table);
      log::info("Table 1 on {} / {}: max error linear {:.2f} %, hybrid 1 ref {:.2f} %, 3 refs "
                "{:.2f} % of the height; per frame {:.1f} us, {:.1f} us, {:.1f} us, non-linear "
                "{:.1f} ms ({:.1f} s)",
                table.take_a, table.take_b, table.linear.max_error_pct,
                table.hybrid1.max_error_pct, table.hybrid3.max_error_pct,
                1e6 * table.linear.seconds_per_frame, 1e6 * table.hybrid1.seconds_per_frame,
                1e6 * table.hybrid3.seconds_per_frame, 1e3 * table.nonlinear.seconds_per_frame,
                table_timer.seconds());
    }
  }
  summary["parameter_error_pct"] = parameter_error;
  write_file_atomic(staged.path() / "summary.json", summary.dump(1));
  YAML::Emitter emitter;
  emitter << to_yaml(options);
  write_file_atomic(staged.path() / "options.yaml", std::string(emitter.c_str()) + "\n");
  staged.commit();
  log::info("wrote {}", out.string());
}

}  // namespace fourd::motionspace
