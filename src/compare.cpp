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

#include <algorithm>
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

/// The error of a final state against the reference, in parts that do not mix units: position and momentum
/// relative to the size of the problem (max(|x_ref|, |x0|), likewise p; absolute where both are 0, as for a
/// body at rest at the origin), the attitude as the angle of R_ref^T R (radians; the sign of q does not
/// matter) and the body angular velocity relative to max(|w_ref|, |w0|).
struct StateError {
  double position = 0, attitude = 0, momentum = 0, angular_velocity = 0;
  /// The largest part: dimensionless, so it compares across problems.
  double max() const { return std::max({position, attitude, momentum, angular_velocity}); }
};

double relative(const Vector3<double>& a, const Vector3<double>& ref, const Vector3<double>& start) {
  const double scale = std::max(ref.norm(), start.norm());
  return scale > 0 ? (a - ref).norm() / scale : (a - ref).norm();
}

StateError state_error(const RigidBodyState& a, const RigidBodyState& ref, const RigidBodyState& start) {
  StateError e;
  e.position = relative(a.x, ref.x, start.x);
  e.momentum = relative(a.p, ref.p, start.p);
  e.angular_velocity = relative(a.w, ref.w, start.w);
  // |<q, q_ref>| = cos(theta/2) for unit quaternions; atan2 keeps small angles accurate.
  const Eigen::Matrix3d d = ref.q.matrix().transpose() * a.q.matrix();
  const Eigen::Vector3d axis(d(2, 1) - d(1, 2), d(0, 2) - d(2, 0), d(1, 0) - d(0, 1));
  e.attitude = std::atan2(0.5 * axis.norm(), 0.5 * (d.trace() - 1.0));
  return e;
}

/// Wall times of repeated runs: median and quartiles (linear interpolation between order statistics).
struct Timing {
  double median = std::nan(""), q25 = std::nan(""), q75 = std::nan("");
  int repeats = 0;
  /// Whether the quartile intervals of two timings overlap: a ranking between them is within the noise.
  bool overlaps(const Timing& o) const { return !(q75 < o.q25 || o.q75 < q25); }
  Timing scaled(double f) const { return {median * f, q25 * f, q75 * f, repeats}; }
};

Timing timing_of(std::vector<double> walls) {
  Timing t;
  if (walls.empty()) return t;
  std::sort(walls.begin(), walls.end());
  const auto quantile = [&](double q) {
    const double pos = q * static_cast<double>(walls.size() - 1);
    const auto i = static_cast<std::size_t>(pos);
    const double f = pos - static_cast<double>(i);
    return i + 1 < walls.size() ? walls[i] * (1 - f) + walls[i + 1] * f : walls[i];
  };
  t.median = quantile(0.5);
  t.q25 = quantile(0.25);
  t.q75 = quantile(0.75);
  t.repeats = static_cast<int>(walls.size());
  return t;
}

struct LadderPoint {
  double h = 0, error = 0, max_energy_error = 0;
  StateError parts;
  Timing wall;
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

namespace {
/// Repeats of one timed run: at least this many, and until their wall times add up to the budget.
constexpr int kMinRepeats = 3;
constexpr int kMaxRepeats = 100000;

/// "1.23e-03 [1.20e-03, 1.31e-03]" (median [q25, q75]), in units of `unit` seconds.
std::string fmt_timing(const Timing& t, double unit, const char* spec) {
  if (!std::isfinite(t.median)) return "-";
  return fmt::format(fmt::runtime(std::string("{:") + spec + "} [{:" + spec + "}, {:" + spec + "}]"),
                     t.median / unit, t.q25 / unit, t.q75 / unit);
}
}  // namespace

int compare_methods(const Scenario& base, const CompareOptions& opt) {
  if (opt.methods.empty()) throw InvalidInput("--methods: name at least one method");
  if (opt.ladder < 2 || opt.ladder > 12) throw InvalidInput("--ladder: must be between 2 and 12");
  if (opt.long_steps < 1) throw InvalidInput("--long-steps: must be >= 1");
  if (!(opt.timing_budget >= 0) || opt.timing_budget > 1e4)
    throw InvalidInput("--timing-budget: must be between 0 and 1e4 seconds");
  for (const MethodChoice& m : opt.methods)
    if (m.method == Method::Exact && base.potential.kind != PotentialKind::None)
      throw InvalidInput("--methods: \"exact\" is the free body's flow; the scenario's potential is not \"none\"");
  const std::string dir = opt.out_dir.empty() ? base.name + "-compare" : opt.out_dir;
  const double h = base.integrator.step;
  const double T = opt.error_time > 0 ? opt.error_time : std::min(base.integrator.duration, 1e4 * h);
  if (!(T > 0)) throw InvalidInput("--error-time: the scenario's duration is 0; give --error-time T > 0");
  if (!(opt.ladder_from >= 0.0) || opt.ladder_from > T)
    throw InvalidInput("--ladder-from: must be a step > 0 and below the error time T = " + fmt::format("{}", T));
  require_new_output_folder(dir, opt.force);
  fs::create_directories(dir);
  const double h0 = opt.ladder_from > 0.0 ? opt.ladder_from : h;
  const double h_min = h0 / std::pow(2.0, opt.ladder - 1);
  const bool free_body = base.potential.kind == PotentialKind::None;
  const std::string reference_name =
      free_body ? std::string("the exact flow") : fmt::format("RK4 with step {:.3g}", h_min / 8);
  if (!opt.quiet) std::cerr << fmt::format("lgvi compare: reference ({}) to t = {}\n", reference_name, T);
  const RigidBodyState reference = reference_state(base, T, h_min / 8);
  const RigidBodyState start = base.initial();

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
      // The results are those of the first run (every repeat computes the same numbers). The first run is
      // also the warm-up (cold caches, the first method's page faults): it is not timed unless it failed.
      // The timed repeats follow, until they add up to the budget (a single sub-millisecond run is noise).
      std::vector<double> walls;
      if (!r.completed) walls.push_back(r.wall_seconds);
      double total = 0;
      while (r.completed && static_cast<int>(walls.size()) < kMaxRepeats &&
             (static_cast<int>(walls.size()) < kMinRepeats || total < opt.timing_budget)) {
        MemorySink again(2);
        walls.push_back(simulate(sc, again).wall_seconds);
        total += walls.back();
      }
      p.wall = timing_of(walls);
      p.completed = r.completed;
      p.failure = r.error;
      if (r.completed) p.parts = state_error(r.final_state.body(0), reference, start);
      p.error = r.completed ? p.parts.max() : std::nan("");
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

  // Files. The timing columns are the only ones that change from one comparison to the next.
  std::string wp =
      "method,h,steps,potential_evaluations,wall_seconds,wall_seconds_q25,wall_seconds_q75,timing_repeats,error,"
      "position_error,attitude_error_rad,momentum_error,angular_velocity_error,max_abs_energy_error,completed\n";
  for (const MethodChoice& m : opt.methods)
    for (const LadderPoint& p : ladder[m])
      wp += fmt::format("{},{},{},{},{},{},{},{},{},{},{},{},{},{},{}\n", m.name(), json_number(p.h), p.steps,
                        p.evaluations, json_number(p.wall.median), json_number(p.wall.q25),
                        json_number(p.wall.q75), p.wall.repeats, json_number(p.error),
                        json_number(p.completed ? p.parts.position : std::nan("")),
                        json_number(p.completed ? p.parts.attitude : std::nan("")),
                        json_number(p.completed ? p.parts.momentum : std::nan("")),
                        json_number(p.completed ? p.parts.angular_velocity : std::nan("")),
                        json_number(p.max_energy_error), p.completed ? "true" : "false");
  write_file_atomically((fs::path(dir) / "work_precision.csv").string(), wp);
  std::string lt = "method,t,energy_error,quat_norm_error,momentum_error\n";
  for (const MethodChoice& m : opt.methods) {
    const auto& rows = long_runs[m].rows;
    for (std::size_t i = 0; i + 4 <= rows.size(); i += 4)
      lt += fmt::format("{},{},{},{},{}\n", m.name(), json_number(rows[i]), json_number(rows[i + 1]),
                        json_number(rows[i + 2]), json_number(rows[i + 3]));
  }
  write_file_atomically((fs::path(dir) / "long_time.csv").string(), lt);

  // ns per step at the finest step, with its quartiles.
  const auto ns_per_step = [](const LadderPoint& p) {
    return p.steps ? p.wall.scaled(1e9 / static_cast<double>(p.steps)) : Timing{};
  };
  const Timing lgvi_ns = [&] {
    for (const MethodChoice& m : opt.methods)
      if (m == MethodChoice{}) return ns_per_step(ladder[m].back());
    return Timing{};
  }();
  std::string csv =
      "method,evaluations_per_step,observed_order,error_at_h,error_at_h_min,position_error_at_h_min,"
      "attitude_error_rad_at_h_min,momentum_error_at_h_min,angular_velocity_error_at_h_min,ns_per_step,"
      "ns_per_step_q25,ns_per_step_q75,timing_repeats,ns_per_step_vs_lgvi,vs_lgvi_within_noise,"
      "long_h,long_max_abs_energy_error,long_final_energy_error,long_max_abs_quat_norm_error,"
      "long_max_relative_momentum_error,long_completed\n";
  const std::string cost_note =
      free_body ? "The scenario has no potential: a free body's cost is its wall time only, and the long runs are "
                  "at equal right-hand-side evaluations (stages) per unit time, e stages per step -> step e h"
                : "Cost: potential evaluations (deterministic) and wall time. Long time: a method needing e "
                  "potential evaluations per step runs with step e h (equal cost)";
  // Where the scenario does not conserve the total angular momentum (a
  // uniform field, a pivot, J2, a forcing), its change is physics, not the
  // method's error: the column says so.
  const std::string momentum_column =
      conservation_laws(base).angular_momentum == ConservationLaws::Angular::Conserved
          ? "momentum error"
          : "momentum change (not conserved here)";
  std::string md = fmt::format(
      "# Comparison on `{}`\n\nWork-precision: steps h = {} ... {} to t = {} against {}. Error = the largest of "
      "|x - x_ref| / max(|x_ref|, |x0|), the attitude angle of R_ref^T R (rad), |p - p_ref| / max(|p_ref|, |p0|) "
      "and |w - w_ref| / max(|w_ref|, |w0|) (absolute where the scale is 0): dimensionless, comparable across "
      "problems; the parts are in work_precision.csv and comparison.csv.\n"
      "Observed order: from the finest pair of steps whose errors lie in [1e-10, 0.1].\n"
      "Timings: after an untimed first run, each run repeated until the repeats add up to {} s (at least {}); "
      "median [first quartile, third quartile]; \"within noise\" where the quartile intervals overlap.\n"
      "{}; {} steps of h.\n\n"
      "| method | {}/step | observed order | error at h | error at h/{} | attitude error at h/{} (rad) | "
      "ns/step, median [quartiles] | vs lgvi | long: max abs energy error | long: max abs(abs(q) - 1) | long: max rel. {} |\n"
      "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|\n",
      base.name, h0, h_min, T, reference_name, opt.timing_budget, kMinRepeats, cost_note, opt.long_steps,
      free_body ? "stages" : "evaluations", 1 << (opt.ladder - 1), 1 << (opt.ladder - 1), momentum_column);
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
    const Timing ns = ns_per_step(b);
    const double vs = ns.median / lgvi_ns.median;
    const bool is_lgvi = m == MethodChoice{};
    const bool noise = !is_lgvi && std::isfinite(vs) && ns.overlaps(lgvi_ns);
    const LongRun& L = long_runs[m];
    const auto part = [&](double v) { return json_number(b.completed ? v : std::nan("")); };
    csv += fmt::format("{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{}\n", m.name(),
                       json_number(per_step), json_number(order), json_number(pts.front().error),
                       json_number(b.error), part(b.parts.position), part(b.parts.attitude),
                       part(b.parts.momentum), part(b.parts.angular_velocity), json_number(ns.median),
                       json_number(ns.q25), json_number(ns.q75), ns.repeats, json_number(vs),
                       noise ? "true" : "false", json_number(L.h), json_number(L.max_energy_error),
                       json_number(L.final_energy_error), json_number(L.max_quat), json_number(L.max_rel_momentum),
                       L.completed ? "true" : "false");
    md += fmt::format("| {} | {:.2f} | {:.2f} | {} | {} | {} | {} | {} | {} | {} | {} |\n", m.name(), per_step,
                      order, fmt_e(pts.front().error), fmt_e(b.error),
                      fmt_e(b.completed ? b.parts.attitude : std::nan("")), fmt_timing(ns, 1.0, ".0f"),
                      !std::isfinite(vs) ? std::string("-")
                      : noise            ? fmt::format("{:.2f} (within noise)", vs)
                                         : fmt::format("{:.2f}", vs),
                      L.completed ? fmt_e(L.max_energy_error) : fmt::format("failed at t = {}", L.steps * L.h),
                      fmt_e(L.max_quat), fmt_e(L.max_rel_momentum));
  }
  // Who keeps the energy error below a target at the least cost (from the ladder): by potential evaluations
  // where there is a potential, and by the median wall time; the exact flow is the reference, not a
  // contender. A wall-time winner whose quartiles overlap the runner-up's (another method) is "within noise".
  md += free_body ? "\nLeast cost to keep max |E - E0| over [0, T] below a target (from the ladder; the exact flow "
                    "is the reference and not ranked; no potential, so by wall time only):\n\n"
                    "| target | least wall time (median) |\n|---|---|\n"
                  : "\nLeast cost to keep max |E - E0| over [0, T] below a target (from the ladder):\n\n"
                    "| target | fewest potential evaluations | least wall time (median) |\n|---|---|---|\n";
  for (double target : {1e-4, 1e-6, 1e-8, 1e-10, 1e-12}) {
    std::string by_evals = "none of the runs", by_time = "none of the runs";
    std::int64_t best_evals = -1;
    // The fastest qualifying point of each method.
    std::map<MethodChoice, const LadderPoint*> fastest;
    for (const MethodChoice& m : opt.methods) {
      if (m.method == Method::Exact) continue;
      for (const LadderPoint& p : ladder[m]) {
        if (!p.completed || !(p.max_energy_error <= target)) continue;
        if (best_evals < 0 || p.evaluations < best_evals) {
          best_evals = p.evaluations;
          by_evals = fmt::format("{} (h = {}, {} evaluations)", m.name(), p.h, p.evaluations);
        }
        auto& f = fastest[m];
        if (!f || p.wall.median < f->wall.median) f = &p;
      }
    }
    const std::pair<const MethodChoice, const LadderPoint*>* winner = nullptr;
    for (const auto& entry : fastest)
      if (!winner || entry.second->wall.median < winner->second->wall.median) winner = &entry;
    if (winner) {
      std::string close;
      for (const auto& entry : fastest)
        if (&entry != winner && entry.second->wall.overlaps(winner->second->wall))
          close += (close.empty() ? "" : ", ") + entry.first.name();
      by_time = fmt::format("{} (h = {}, {} s){}", winner->first.name(), winner->second->h,
                            fmt_timing(winner->second->wall, 1.0, ".3g"),
                            close.empty() ? "" : "; within noise of " + close);
    }
    md += free_body ? fmt::format("| {:.0e} | {} |\n", target, by_time)
                    : fmt::format("| {:.0e} | {} | {} |\n", target, by_evals, by_time);
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
  if (!opt.quiet) std::cout << fmt::format("\nlgvi compare: output in {}\n", dir);
  return kSuccess;
}

}  // namespace lgvi::app
