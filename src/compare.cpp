#include "compare.hpp"

#include "memory_sink.hpp"
#include "output.hpp"
#include "run.hpp"
#include "simulation.hpp"

#include <lgvi/continuous.hpp>
#include <lgvi/error.hpp>
#include <lgvi/exact_free_body.hpp>
#include <lgvi/potential.hpp>

#include <fmt/format.h>

#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <iostream>
#include <map>
#include <variant>

namespace lgvi::app {

namespace fs = std::filesystem;

namespace {

/// The reference state at time T: for a free body the exact flow; otherwise
/// RK4 of the continuous equations with step h_ref (its error C h_ref^4 is
/// then far below every method's).
RigidBodyState reference_state(const Scenario& sc, double T, double h_ref) {
  if (sc.potential.kind == PotentialKind::None) return ExactFreeRigidBody(sc.body(), sc.initial()).at(T);
  const auto n = static_cast<long>(std::ceil(T / h_ref - 1e-9));
  const double h = T / static_cast<double>(n);
  // The scenario's own potential, as the runs compared against it use.
  return std::visit(
      [&](const auto& potential) {
        const ContinuousEquations eqs(sc.body(), potential);
        return from_continuous(eqs.rk4(to_continuous(sc.initial(), sc.body()), h, n), sc.body());
      },
      scenario_potential(sc));
}

/// max(|x - x'|, |R - R'|_F, |p - p'|, |w - w'|): the sign of q does not matter.
double state_error(const RigidBodyState& a, const RigidBodyState& b) {
  return std::max({(a.x - b.x).norm(), (a.q.matrix() - b.q.matrix()).norm(), (a.p - b.p).norm(), (a.w - b.w).norm()});
}

struct LadderPoint {
  double h = 0, error = 0, wall = 0, max_energy_error = 0;
  std::int64_t steps = 0, evaluations = 0;
  bool completed = false;
  std::string failure;
};

struct LongRun {
  double h = 0, wall = 0, max_energy_error = 0, final_energy_error = 0, max_quat = 0, max_rel_momentum = 0;
  std::int64_t steps = 0, evaluations = 0;
  bool completed = false;
  std::string failure;
  std::vector<double> rows;  // t, energy_error, quat_norm_error, momentum_error
};


std::string fmt_e(double v) { return std::isfinite(v) ? fmt::format("{:.3e}", v) : "-"; }

}  // namespace

std::string MethodChoice::name() const {
  return order == 2 ? std::string(to_string(method)) : fmt::format("{}:{}", to_string(method), order);
}

MethodChoice method_choice_from_string(const std::string& text) {
  MethodChoice c;
  const std::size_t colon = text.find(':');
  c.method = method_from_string(text.substr(0, colon), "--methods");
  if (colon == std::string::npos) return c;
  const std::string order = text.substr(colon + 1);
  if (order != "2" && order != "4" && order != "6" && order != "8")
    throw InvalidInput("key '--methods': \"" + text + "\": the order after ':' must be 2, 4, 6 or 8");
  c.order = std::stoi(order);
  if (c.order != 2 && !is_composable(c.method))
    throw InvalidInput("key '--methods': \"" + text + "\": " + to_string(c.method) +
                       " cannot be composed to higher order (symmetric one-step methods only: lgvi, so3-lgvi, "
                       "rattle-quaternion, no-squish, splitting-dlm)");
  return c;
}

namespace {
/// The scenario run with method choice m.
Scenario with_method(const Scenario& base, const MethodChoice& m) {
  Scenario sc = base;
  sc.integrator.method = m.method;
  sc.integrator.composition = CompositionTable::of_order(m.order);
  return sc;
}
}  // namespace

int compare_methods(const Scenario& base, const CompareOptions& opt) {
  if (opt.methods.empty()) throw InvalidInput("--methods: name at least one method");
  if (opt.ladder < 2 || opt.ladder > 12) throw InvalidInput("--ladder: must be between 2 and 12");
  if (opt.long_steps < 1) throw InvalidInput("--long-steps: must be >= 1");
  for (const MethodChoice& m : opt.methods)
    if (m.method == Method::Exact && base.potential.kind != PotentialKind::None)
      throw InvalidInput("--methods: \"exact\" is the free body's flow; the scenario's potential is not \"none\"");
  const std::string dir = opt.out_dir.empty() ? base.name + "-compare" : opt.out_dir;
  fs::create_directories(dir);
  const double h = base.integrator.step;
  const double T = opt.error_time > 0 ? opt.error_time : std::min(base.integrator.duration, 1e4 * h);
  if (!(T > 0)) throw InvalidInput("--error-time: the scenario's duration is 0; give --error-time T > 0");
  if (!(opt.ladder_from >= 0.0) || opt.ladder_from > T)
    throw InvalidInput("--ladder-from: must be a step > 0 and below the error time T = " + fmt::format("{}", T));
  const double h0 = opt.ladder_from > 0.0 ? opt.ladder_from : h;
  const double h_min = h0 / std::pow(2.0, opt.ladder - 1);
  const bool free_body = base.potential.kind == PotentialKind::None;
  const std::string reference_name =
      free_body ? std::string("the exact flow") : fmt::format("RK4 with step {:.3g}", h_min / 8);
  if (!opt.quiet) std::cerr << fmt::format("lgvi compare: reference ({}) to t = {}\n", reference_name, T);
  const RigidBodyState reference = reference_state(base, T, h_min / 8);

  std::map<MethodChoice, std::vector<LadderPoint>> ladder;
  std::map<MethodChoice, LongRun> long_runs;
  for (const MethodChoice& m : opt.methods) {
    if (!opt.quiet) std::cerr << fmt::format("lgvi compare: {}\n", m.name());
    for (int j = 0; j < opt.ladder; ++j) {
      Scenario sc = with_method(base, m);
      sc.integrator.step = h0 / std::pow(2.0, j);
      sc.integrator.steps = std::llround(T / sc.integrator.step);
      sc.output_every = sc.integrator.steps + 1;  // first and last rows only
      MemorySink sink(2);
      LadderPoint p;
      p.h = sc.integrator.step;
      const SimulationResult r = simulate(sc, sink);
      p.completed = r.completed;
      p.failure = r.error;
      p.error = r.completed ? state_error(r.final_state.body(0), reference) : std::nan("");
      p.wall = r.wall_seconds;
      p.steps = r.stats.last_k;
      p.evaluations = r.stats.potential_evaluations;
      p.max_energy_error = r.stats.max_energy_error;
      ladder[m].push_back(p);
    }
    // Long run at equal cost: e evaluations per step -> step e h.
    const auto& first = ladder[m].front();
    const double per_step = first.steps > 0 && first.evaluations > 0
                                ? static_cast<double>(first.evaluations - 1) / static_cast<double>(first.steps)
                                : 1.0;
    const double cost_factor = std::max(1.0, std::round(per_step));
    Scenario sc = with_method(base, m);
    sc.integrator.step = h * cost_factor;
    sc.integrator.steps = static_cast<std::int64_t>(static_cast<double>(opt.long_steps) / cost_factor);
    sc.output_every = std::max<std::int64_t>(1, sc.integrator.steps / 2000);
    MemorySink sink(2100);
    const SimulationResult r = simulate(sc, sink);
    LongRun& L = long_runs[m];
    L.h = sc.integrator.step;
    L.completed = r.completed;
    L.failure = r.error;
    L.wall = r.wall_seconds;
    L.steps = r.stats.last_k;
    L.evaluations = r.stats.potential_evaluations;
    L.max_energy_error = r.stats.max_energy_error;
    L.max_quat = r.stats.max_quat_error;
    const double l0 = r.stats.momentum0.norm();
    L.max_rel_momentum = l0 > 0 ? r.stats.max_momentum_error / l0 : r.stats.max_momentum_error;
    const std::vector<double> rows = sink.take();
    for (std::size_t i = 0; i + trajectory_columns <= rows.size(); i += trajectory_columns)
      L.rows.insert(L.rows.end(), {rows[i], rows[i + 15], rows[i + 16], rows[i + 20]});
    L.final_energy_error = L.rows.size() >= 4 ? L.rows[L.rows.size() - 3] : std::nan("");
  }

  // Files.
  std::string wp = "method,h,steps,potential_evaluations,wall_seconds,error,max_abs_energy_error,completed\n";
  for (const MethodChoice& m : opt.methods)
    for (const LadderPoint& p : ladder[m])
      wp += fmt::format("{},{},{},{},{},{},{},{}\n", m.name(), json_number(p.h), p.steps, p.evaluations,
                        json_number(p.wall), json_number(p.error), json_number(p.max_energy_error),
                        p.completed ? "true" : "false");
  write_file_atomically((fs::path(dir) / "work_precision.csv").string(), wp);
  std::string lt = "method,t,energy_error,quat_norm_error,momentum_error\n";
  for (const MethodChoice& m : opt.methods) {
    const auto& rows = long_runs[m].rows;
    for (std::size_t i = 0; i + 4 <= rows.size(); i += 4)
      lt += fmt::format("{},{},{},{},{}\n", m.name(), json_number(rows[i]), json_number(rows[i + 1]),
                        json_number(rows[i + 2]), json_number(rows[i + 3]));
  }
  write_file_atomically((fs::path(dir) / "long_time.csv").string(), lt);

  const double lgvi_ns = [&] {
    for (const MethodChoice& m : opt.methods)
      if (m == MethodChoice{}) {
        const auto& p = ladder[m].back();
        return p.steps ? p.wall * 1e9 / static_cast<double>(p.steps) : std::nan("");
      }
    return std::nan("");
  }();
  std::string csv =
      "method,evaluations_per_step,observed_order,error_at_h,error_at_h_min,ns_per_step,ns_per_step_vs_lgvi,"
      "long_h,long_max_abs_energy_error,long_final_energy_error,long_max_abs_quat_norm_error,"
      "long_max_relative_momentum_error,long_completed\n";
  std::string md = fmt::format(
      "# Comparison on `{}`\n\nWork-precision: steps h = {} ... {} to t = {}; error = max(|x - x_ref|, "
      "|R - R_ref|_F, |p - p_ref|, |w - w_ref|) against {}.\n"
      "Observed order: from the finest pair of steps whose errors lie in [1e-10, 0.1].\n"
      "Long time: {} steps of h for one evaluation per step; a method needing e evaluations per step runs "
      "with step e h (equal cost).\n\n"
      "| method | evaluations/step | observed order | error at h | error at h/{} | ns/step | vs lgvi | "
      "long: max abs energy error | long: max abs(abs(q) - 1) | long: max rel. momentum error |\n"
      "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|\n",
      base.name, h0, h_min, T, reference_name, opt.long_steps, 1 << (opt.ladder - 1));
  for (const MethodChoice& m : opt.methods) {
    const auto& pts = ladder[m];
    const LadderPoint& b = pts.back();
    // Observed order: log2 of the error ratio of the last pair of successive
    // steps whose errors are both in [1e-10, 0.1], i.e. past the
    // pre-asymptotic regime and above the round-off floor (the finest RK4
    // runs reach ~1e-11, where rounding, not truncation, is measured).
    double order = std::nan("");
    for (std::size_t j = 0; j + 1 < pts.size(); ++j) {
      const double e0 = pts[j].error, e1 = pts[j + 1].error;
      if (e0 >= 1e-10 && e0 <= 0.1 && e1 >= 1e-10 && e1 <= 0.1) order = std::log2(e0 / e1);
    }
    // No pair in range (errors saturated, or a run failed): no order ("nan").
    // The initialize() evaluation is not a step's.
    const double per_step =
        b.steps && b.evaluations > 0 ? static_cast<double>(b.evaluations - 1) / static_cast<double>(b.steps) : 0.0;
    const double ns = b.steps ? b.wall * 1e9 / static_cast<double>(b.steps) : std::nan("");
    const LongRun& L = long_runs[m];
    csv += fmt::format("{},{},{},{},{},{},{},{},{},{},{},{},{}\n", m.name(), json_number(per_step),
                       json_number(order), json_number(pts.front().error), json_number(b.error), json_number(ns),
                       json_number(ns / lgvi_ns), json_number(L.h), json_number(L.max_energy_error),
                       json_number(L.final_energy_error), json_number(L.max_quat),
                       json_number(L.max_rel_momentum), L.completed ? "true" : "false");
    md += fmt::format("| {} | {:.2f} | {:.2f} | {} | {} | {:.0f} | {:.2f} | {} | {} | {} |\n", m.name(), per_step,
                      order, fmt_e(pts.front().error), fmt_e(b.error), ns, ns / lgvi_ns,
                      L.completed ? fmt_e(L.max_energy_error)
                                  : fmt::format("failed at t = {}", L.steps * L.h),
                      fmt_e(L.max_quat), fmt_e(L.max_rel_momentum));
  }
  // Who keeps the energy error below a target at the least cost (from the
  // ladder), by potential evaluations and by wall time (for a free body the
  // evaluations cost nothing and only the time tells).
  md += "\nLeast cost to keep max |E - E0| over [0, T] below a target (from the ladder):\n\n"
        "| target | fewest potential evaluations | least wall time |\n|---|---|---|\n";
  for (double target : {1e-4, 1e-6, 1e-8, 1e-10, 1e-12}) {
    std::string by_evals = "none of the runs", by_time = "none of the runs";
    std::int64_t best_evals = -1;
    double best_time = -1;
    for (const MethodChoice& m : opt.methods)
      for (const LadderPoint& p : ladder[m]) {
        if (!p.completed || !(p.max_energy_error <= target)) continue;
        if (best_evals < 0 || p.evaluations < best_evals) {
          best_evals = p.evaluations;
          by_evals = fmt::format("{} (h = {}, {} evaluations)", m.name(), p.h, p.evaluations);
        }
        if (best_time < 0 || p.wall < best_time) {
          best_time = p.wall;
          by_time = fmt::format("{} (h = {}, {:.3g} s)", m.name(), p.h, p.wall);
        }
      }
    md += fmt::format("| {:.0e} | {} | {} |\n", target, by_evals, by_time);
  }
  write_file_atomically((fs::path(dir) / "comparison.csv").string(), csv);
  write_file_atomically((fs::path(dir) / "comparison.md").string(), md);
  if (!opt.quiet) std::cout << md;
  if (opt.figures) {
    try {
      draw_compare_figures(dir);
    } catch (const std::exception& e) {
      std::cerr << "lgvi: error: the comparison's tables are written, but " << e.what() << "\n";
      return kRunFailed;
    }
  }
  return kSuccess;
}

}  // namespace lgvi::app
