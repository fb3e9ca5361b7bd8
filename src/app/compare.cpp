#include "app/compare.hpp"

#include "io/memory_sink.hpp"
#include "io/output.hpp"
#include "app/run.hpp"
#include "app/simulation.hpp"

#include <lgvi/continuous.hpp>
#include <lgvi/error.hpp>
#include <lgvi/exact_free_body.hpp>
#include <lgvi/potential.hpp>
#include <lgvi/time_transformed.hpp>

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <iostream>
#include <limits>
#include <map>
#include <optional>
#include <stdexcept>
#include <string_view>
#include <variant>

namespace lgvi::app {

namespace fs = std::filesystem;

namespace {

/// The reference state at time T: for a free body (three moments) the exact flow; otherwise
/// RK4 of the continuous equations with step h_ref (its error C h_ref^4 is
/// then far below every method's), or, `transformed`, RK4 of them in the
/// fictitious time of the adaptive runs' time transformation with step h_ref
/// (ContinuousEquations::rk4_time_transformed; their monitor, the scenario's c
/// or |V| at the start): smooth through a close pass.
RigidBodyState reference_state(const Scenario& sc, double T, double h_ref, bool transformed) {
  // (A linear body's free flow is RK4's too: the exact flow is for three moments.)
  if (sc.potential.kind == PotentialKind::None && sc.body().rotational_dof() == 3)
    return ExactFreeRigidBody(sc.body(), sc.initial()).at(T);
  const auto n = static_cast<long>(std::ceil(T / h_ref - 1e-9));
  const double h = T / static_cast<double>(n);
  // The scenario's own potential, as the runs compared against it use.
  return std::visit(
      [&](const auto& potential) {
        const ContinuousEquations eqs(sc.body(), potential);
        const ContinuousState start = to_continuous(sc.initial(), sc.body());
        if (!transformed) return from_continuous(eqs.rk4(start, h, n), sc.body());
        const double c = sc.integrator.monitor_scale > 0.0
                             ? sc.integrator.monitor_scale
                             : std::abs(potential.evaluate(sc.initial().x, sc.initial().q).energy);
        const auto g = [c](double u) { return time_transform_monitor(u, c); };
        return from_continuous(eqs.rk4_time_transformed(start, 0.0, T, h_ref, g), sc.body());
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

/// The angle of R_ref^T R in radians (the sign of q does not matter).
double attitude_angle(const RigidBodyState& a, const RigidBodyState& ref) {
  // |<q, q_ref>| = cos(theta/2) for unit quaternions; atan2 keeps small angles accurate.
  const Eigen::Matrix3d d = ref.q.matrix().transpose() * a.q.matrix();
  const Eigen::Vector3d axis(d(2, 1) - d(1, 2), d(0, 2) - d(2, 0), d(1, 0) - d(0, 1));
  return std::atan2(0.5 * axis.norm(), 0.5 * (d.trace() - 1.0));
}

StateError state_error(const RigidBodyState& a, const RigidBodyState& ref, const RigidBodyState& start) {
  StateError e;
  e.position = relative(a.x, ref.x, start.x);
  e.momentum = relative(a.p, ref.p, start.p);
  e.angular_velocity = relative(a.w, ref.w, start.w);
  e.attitude = attitude_angle(a, ref);
  return e;
}

/// Whether the scenario is compared as a system ([[bodies]], several bodies or an interaction): against a
/// converged order-8 lgvi run (converged_reference), with per-body errors (system_error). The single-body
/// scenarios keep their references (the exact flow, RK4 of the continuous equations).
bool is_system(const Scenario& sc) {
  return sc.many_body_form || sc.bodies() > 1 || !sc.interaction.none();
}

/// The system's mass-weighted centre.
Vector3<double> centre_of_mass(const System& sys, const SystemState& s) {
  Vector3<double> c = Vector3<double>::Zero();
  for (std::size_t a = 0; a < s.size(); ++a) c += sys.body(a).mass() * s.x[a];
  return c / sys.total_mass();
}

/// The error of a system's final state, per body, each part the largest over the bodies, relative to the
/// system's scales taken over the reference and the start: positions to L = the largest distance of a body
/// from the centre of mass (one body: the largest |x_a|, as state_error's), momenta to the largest |p_b|,
/// angular velocities to the largest |w_b| (absolute where a scale is 0); the attitude angle in radians.
/// One scale per quantity, not per body: a light body's error counts at the system's size, not its own.
StateError system_error(const System& sys, const SystemState& s, const SystemState& ref, const SystemState& start) {
  const Vector3<double> c_ref = centre_of_mass(sys, ref), c0 = centre_of_mass(sys, start);
  double lx = 0, lx_origin = 0, lp = 0, lw = 0;
  for (std::size_t a = 0; a < s.size(); ++a) {
    lx = std::max({lx, (ref.x[a] - c_ref).norm(), (start.x[a] - c0).norm()});
    lx_origin = std::max({lx_origin, ref.x[a].norm(), start.x[a].norm()});
    lp = std::max({lp, ref.p[a].norm(), start.p[a].norm()});
    lw = std::max({lw, ref.w[a].norm(), start.w[a].norm()});
  }
  if (lx == 0) lx = lx_origin;
  const auto scaled = [](double d, double scale) { return scale > 0 ? d / scale : d; };
  StateError e;
  for (std::size_t a = 0; a < s.size(); ++a) {
    e.position = std::max(e.position, scaled((s.x[a] - ref.x[a]).norm(), lx));
    e.attitude = std::max(e.attitude, attitude_angle(s.body(a), ref.body(a)));
    e.momentum = std::max(e.momentum, scaled((s.p[a] - ref.p[a]).norm(), lp));
    e.angular_velocity = std::max(e.angular_velocity, scaled((s.w[a] - ref.w[a]).norm(), lw));
  }
  return e;
}

/// Why the adaptive LGVI cannot run the scenario (scenario.cpp's time_transform_refusal); empty if it can.
std::string time_transform_not_applicable(const Scenario& sc) {
  const auto refusal = time_transform_refusal(sc.potential, sc.interaction, !sc.forcing.empty());
  return refusal ? "the adaptive step (" + refusal->key + "): " + refusal->reason : std::string();
}

/// Why method choice m cannot run the scenario, as the table says it; empty if it can. The reader's checks
/// on [integrator] method and time_transform (scenario.cpp), asked of every compared method.
std::string not_applicable(const Scenario& sc, const MethodChoice& m) {
  if (m.time_transformed) return time_transform_not_applicable(sc);
  const MethodTraits& t = m.method.traits();
  if (t.free_body_only && (sc.bodies() > 1 || !sc.interaction.none() || sc.potential.kind != PotentialKind::None))
    return fmt::format("the exact flow of one free body; this scenario has {} bod{}{}{}", sc.bodies(),
                       sc.bodies() == 1 ? "y" : "ies",
                       !sc.interaction.none() ? ", an [interaction]" : "",
                       sc.potential.kind != PotentialKind::None ? ", a [potential]" : "");
  if (t.needs_principal_axes)
    for (std::size_t a = 0; a < sc.bodies(); ++a)
      if (!sc.system.body(a).has_principal_axes())
        return fmt::format("rotates about the principal axes; {}.inertia is not diagonal",
                           sc.many_body_form ? fmt::format("bodies[{}]", a) : std::string("body"));
  if (!t.linear_bodies)
    for (std::size_t a = 0; a < sc.bodies(); ++a)
      if (sc.system.body(a).rotational_dof() != 3)
        return fmt::format("needs three principal moments > 0; {} is {}",
                           sc.many_body_form ? fmt::format("bodies[{}]", a) : std::string("the body"),
                           sc.system.body(a).rotation_description());
  if (!sc.forcing.empty() && !t.accepts_forcing)
    return "does not take [[forcing]] (" +
           method_names_where([](const MethodTraits& x) { return x.accepts_forcing; }, ", ", " and ", false) + " do)";
  return {};
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
  /// Over [0, T]: |P - P0| relative to sum |p_a0|, |L - L0| relative to |L0| (absolute where the scale is 0).
  double max_linear_momentum_error = 0, max_angular_momentum_error = 0;
  StateError parts;
  Timing wall;
  std::int64_t steps = 0, evaluations = 0;
  bool completed = false;
  std::string failure;
};

struct LongRun {
  double h = 0, wall = 0, max_energy_error = 0, final_energy_error = 0, max_quat = 0, max_rel_momentum = 0;
  double last_t = 0;  ///< the time reached
  std::int64_t steps = 0, evaluations = 0;
  bool completed = false;
  std::string failure;
  std::vector<double> rows;  // t, energy_error, quat_norm_error, momentum_error
};


std::string fmt_e(double v) { return std::isfinite(v) ? fmt::format("{:.3e}", v) : "-"; }

/// `text` as one CSV field (RFC 4180): in double quotes, each double quote in it doubled.
std::string csv_quoted(const std::string& text) {
  std::string quoted = "\"";
  for (const char c : text) quoted += c == '"' ? std::string("\"\"") : std::string(1, c);
  return quoted + "\"";
}

}  // namespace

std::string MethodChoice::name() const {
  const std::string n = order == 2 ? std::string(to_string(method)) : fmt::format("{}:{}", to_string(method), order);
  return time_transformed ? n + "+tt" : n;
}

MethodChoice method_choice_from_string(const std::string& text) {
  MethodChoice c;
  std::string spec = text;
  constexpr std::string_view adaptive = "+tt";
  if (const std::size_t at = spec.find(adaptive); at != std::string::npos && at + adaptive.size() != spec.size())
    throw InvalidInput("key '--methods': \"" + text + "\": +tt goes last, after the order (e.g. lgvi:4+tt)");
  if (spec.size() > adaptive.size() && spec.ends_with(adaptive)) {
    c.time_transformed = true;
    spec.resize(spec.size() - adaptive.size());
  }
  const std::size_t colon = spec.find(':');
  c.method = Method::named(spec.substr(0, colon), "--methods");
  if (c.time_transformed && c.method.traits().name != std::string_view("lgvi"))
    throw InvalidInput("key '--methods': \"" + text + "\": +tt, the adaptive step (time_transform = \"potential\"), "
                       "is built from the LGVI's Hamiltonian form: name lgvi+tt or lgvi:ORDER+tt");
  if (colon == std::string::npos) return c;
  const std::string order = spec.substr(colon + 1);
  if (order != "2" && order != "4" && order != "6" && order != "8")
    throw InvalidInput("key '--methods': \"" + text + "\": the order after ':' must be 2, 4, 6 or 8");
  c.order = std::stoi(order);
  if (c.order != 2 && !c.method.traits().composable())
    throw InvalidInput("key '--methods': \"" + text + "\": " + to_string(c.method) +
                       " cannot be composed to higher order (symmetric one-step methods only: " +
                       method_names_where([](const MethodTraits& t) { return t.composable(); }, ", ", ", ", false) +
                       ")");
  return c;
}

std::vector<MethodChoice> default_method_choices(const Scenario& sc) {
  if (!sc.integrator.adaptive()) return {method_choice_from_string("lgvi"), method_choice_from_string("lgvi-lagrangian")};
  // The scenario's order (a custom composition's is 2: --methods cannot name it, so the plain step).
  const MethodChoice fixed{Method::named("lgvi"), sc.integrator.composition.order(), false};
  return {MethodChoice{fixed.method, fixed.order, true}, fixed};
}

namespace {
/// The scenario run with method choice m: its method and order; with a time
/// transformation (the scenario's monitor_scale) for "+tt", without one otherwise.
Scenario with_method(const Scenario& base, const MethodChoice& m) {
  Scenario sc = base;
  sc.integrator.method = m.method;
  sc.integrator.composition = CompositionTable::of_order(m.order);
  sc.integrator.time_transform = m.time_transformed ? TimeTransform::Potential : TimeTransform::None;
  sc.integrator.exact_finish = false;
  return sc;
}

/// max_steps of an adaptive run of `duration` with fictitious step eps: the reader's default.
std::int64_t adaptive_max_steps(double duration, double eps) {
  if (const auto n = default_max_steps(duration, eps)) return *n;
  throw InvalidInput(fmt::format("--error-time, --long-steps: an adaptive run over {} with epsilon {} would need "
                                 "more than 2^53 steps; shorten it or enlarge --ladder-from",
                                 duration, eps));
}
}  // namespace

namespace {
/// Repeats of one timed run: at least this many, and until their wall times add up to the budget.
constexpr int kMinRepeats = 3;
constexpr int kMaxRepeats = 100000;

/// The scenario run with method choice m at step `step` to t = T (llround(T / step) steps; "+tt": epsilon
/// = step, ending at T exactly), writing its first and last rows only: one point of the ladder.
Scenario ladder_scenario(const Scenario& base, const MethodChoice& m, double step, double T) {
  Scenario sc = with_method(base, m);
  sc.integrator.step = step;
  if (m.time_transformed) {
    sc.integrator.duration = T;
    sc.integrator.exact_finish = true;
    sc.integrator.steps = adaptive_max_steps(T, step);
  } else {
    sc.integrator.steps = std::llround(T / step);
  }
  sc.output_every = sc.integrator.steps + 1;  // first and last rows only
  return sc;
}

/// A system's reference: lgvi composed to order 8 (Kahan & Li's 15 stages; `transformed`: the adaptive
/// lgvi:8+tt, whose step is epsilon, ending at T exactly) at a step h_ref whose halving
/// changes the final state by at most kReferenceTolerance, in the comparison's own error measure
/// (system_error). The steps tried are the ladder's largest h0, h0 / 2, ... down to a quarter of its
/// finest, stopping when the tolerance is met. Past the truncation regime (where a halving divides the
/// change by 256) the change is round-off accumulated over the run, which grows with the number of steps:
/// so the search starts coarse rather than at the finest step, and once the change has failed to fall
/// (by kTruncationShrink below the smallest before it) on kRoundOffHalvings successive halvings, or the
/// steps run out, h_ref is the step of the smallest change seen, and that change, reported with it, is
/// the reference's accuracy. Above kReferenceLimit the comparison fails rather than measure the
/// reference. A run that fails (the composition's sub-steps, some negative, at a large step) only counts
/// as not converged. The compared runs and the reference end at llround(T / h) h, one time for all:
/// compare_methods rounds T to a whole number of the ladder's largest step.
struct SystemReference {
  SystemState state;  ///< the run at h_ref, at t = llround(T / h_ref) h_ref
  double h = 0;       ///< h_ref
  double change = std::numeric_limits<double>::infinity();  ///< system_error(h_ref, h_ref / 2).max()
  bool met = false;   ///< change <= kReferenceTolerance
};
constexpr double kReferenceTolerance = 1e-13;
/// An error of 1e-11 in the reference moves an error of 1e-10, the smallest the observed order uses, by
/// at most 10 % (its order by at most 0.15 over a halving); any larger and the order fit would measure
/// the reference.
constexpr double kReferenceLimit = 1e-11;
constexpr int kRoundOffHalvings = 2;
/// Truncation at order 8 divides the change by 2^8 per halving; a change that falls by less than this
/// factor is round-off (or not yet asymptotic: then a later halving falls again and resets the count).
constexpr double kTruncationShrink = 8.0;

SystemReference converged_reference(const Scenario& base, double T, double h_largest, double h_finest,
                                    bool quiet, bool transformed) {
  const MethodChoice order8{Method::named("lgvi"), 8, transformed};
  const auto final_state = [&](double step) -> std::optional<SystemState> {
    MemorySink sink(2);
    SimulationResult r = simulate(ladder_scenario(base, order8, step, T), sink);
    if (!r.completed) {
      if (!quiet) std::cerr << fmt::format("lgvi compare: reference {}, h = {:.6g}: {}\n", order8.name(), step, r.error);
      return std::nullopt;
    }
    return std::move(r.final_state);
  };
  SystemReference best;
  int not_falling = 0;
  double previous = std::numeric_limits<double>::infinity();
  std::optional<SystemState> coarse = final_state(h_largest);
  for (double h = h_largest; h > h_finest / 3 && !best.met && not_falling < kRoundOffHalvings; h /= 2) {
    std::optional<SystemState> fine = final_state(h / 2);
    const double change = coarse && fine ? system_error(base.system, *coarse, *fine, base.initial_state).max()
                                         : std::numeric_limits<double>::infinity();
    if (!quiet && std::isfinite(change))
      std::cerr << fmt::format("lgvi compare: reference {}, h = {:.6g}: halving it changes the final state by "
                               "{:.3e}\n", order8.name(), h, change);
    if (change < best.change) best = {*coarse, h, change, change <= kReferenceTolerance};
    not_falling = std::isfinite(change) && change * kTruncationShrink > previous ? not_falling + 1 : 0;
    previous = std::min(previous, change);
    coarse = std::move(fine);
  }
  if (!(best.change <= kReferenceLimit))
    throw std::runtime_error(
        std::isfinite(best.change)
            ? fmt::format("compare: the reference ({}) did not converge: at best, halving h_ref = {:.6g} changes "
                          "the final state by {:.3e} (above {:.0e}); give a shorter --error-time",
                          order8.name(), best.h, best.change, kReferenceLimit)
            : fmt::format("compare: the reference runs ({}) failed at every step; give a smaller --ladder-from",
                          order8.name()));
  return best;
}

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
  // The other methods and the references (RK4 of the continuous equations, the exact flow) step rigid bodies:
  // on a gyrostat they would ignore its wheels, a comparison of the wrong dynamics.
  if (base.system.has_wheels())
    throw InvalidInput("lgvi compare: a body with reaction wheels ([[body.wheel]]) is not compared yet (only \"lgvi\" "
                       "steps it; the other methods and the references would treat it as a rigid body): use lgvi run");
  const bool system = is_system(base);
  // A system's table lists the methods that cannot run it, saying why; a single body's comparison refuses
  // them. Either way, at least one method must run.
  std::map<MethodChoice, std::string> unable;
  std::vector<MethodChoice> runnable;
  for (const MethodChoice& m : opt.methods) {
    if (!system && m.method.traits().free_body_only && base.potential.kind != PotentialKind::None)
      throw InvalidInput("--methods: \"" + std::string(m.method.name()) +
                         "\" is the free body's flow; the scenario's potential is not \"none\"");
    if (!system && !m.method.traits().linear_bodies && base.body().rotational_dof() != 3)
      throw InvalidInput("--methods: \"" + std::string(m.method.name()) +
                         "\" needs three principal moments > 0; the body is " +
                         base.body().rotation_description() +
                         "; name lgvi or lgvi-lagrangian");
    if (!system && m.time_transformed)
      if (const std::string why = time_transform_not_applicable(base); !why.empty())
        throw InvalidInput("--methods: \"" + m.name() + "\": " + why + "; name a fixed-step method");
    std::string why = system ? not_applicable(base, m) : std::string();
    if (why.empty())
      runnable.push_back(m);
    else
      unable[m] = std::move(why);
  }
  if (runnable.empty())
    throw InvalidInput("--methods: none of the methods can run this scenario (" + opt.methods.front().name() +
                       ": " + unable.at(opt.methods.front()) + "); name another, e.g. lgvi");
  const std::string dir = opt.out_dir.empty() ? base.name + "-compare" : opt.out_dir;
  const double h = base.integrator.step;
  const double T_asked = opt.error_time > 0 ? opt.error_time : std::min(base.integrator.duration, 1e4 * h);
  if (!(T_asked > 0)) throw InvalidInput("--error-time: the scenario's duration is 0; give --error-time T > 0");
  if (!(opt.ladder_from >= 0.0) || opt.ladder_from > T_asked)
    throw InvalidInput("--ladder-from: must be a step > 0 and below the error time T = " + fmt::format("{}", T_asked));
  const double h0 = opt.ladder_from > 0.0 ? opt.ladder_from : h;
  // Every run ends at llround(T / h) h: unless T is a whole number of the largest step h0 (and so of
  // every h0 / 2^j), the runs and the reference would end at different times and the errors mix in
  // that offset. T is therefore rounded to the nearest multiple of h0, and said so.
  const double multiples = std::max(1.0, std::round(T_asked / h0));
  const double T = std::abs(T_asked / h0 - std::round(T_asked / h0)) <= 1e-9 * (T_asked / h0) ? T_asked : multiples * h0;
  if (T != T_asked && !opt.quiet)
    std::cerr << fmt::format("lgvi compare: error time {} is not a whole number of the largest step {}: compared at "
                             "T = {} ({} steps of it)\n",
                             T_asked, h0, T, multiples);
  require_new_output_folder(dir, opt.force);
  fs::create_directories(dir);
  const double h_min = h0 / std::pow(2.0, opt.ladder - 1);
  // No potential and no interaction: nothing to count but right-hand-side stages.
  const bool free_body = base.potential.kind == PotentialKind::None && base.interaction.none();
  // An adaptive scenario, or an adaptive method among those compared: a close pass may lie within [0, T],
  // which a fixed-step reference cannot follow; the references are then time-transformed too.
  const bool transformed =
      base.integrator.adaptive() ||
      std::any_of(runnable.begin(), runnable.end(), [](const MethodChoice& m) { return m.time_transformed; });
  const SystemReference system_reference =
      system ? converged_reference(base, T, h0, h_min, opt.quiet, transformed) : SystemReference{};
  const std::string reference_name =
      system      ? fmt::format("lgvi:8{} with step {:.3g}", transformed ? "+tt" : "", system_reference.h)
      : free_body ? std::string("the exact flow")
      : transformed
          ? fmt::format("RK4 of the time-transformed equations with step {:.3g} in the fictitious time", h_min / 8)
          : fmt::format("RK4 with step {:.3g}", h_min / 8);
  if (!opt.quiet && !system) std::cerr << fmt::format("lgvi compare: reference ({}) to t = {}\n", reference_name, T);
  const RigidBodyState reference = system ? RigidBodyState{} : reference_state(base, T, h_min / 8, transformed);
  const RigidBodyState start = base.initial();

  std::map<MethodChoice, std::vector<LadderPoint>> ladder;
  std::map<MethodChoice, LongRun> long_runs;
  for (const MethodChoice& m : runnable) {
    if (!opt.quiet) std::cerr << fmt::format("lgvi compare: {}\n", m.name());
    for (int j = 0; j < opt.ladder; ++j) {
      const Scenario sc = ladder_scenario(base, m, h0 / std::pow(2.0, j), T);
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
      if (r.completed)
        p.parts = system ? system_error(base.system, r.final_state, system_reference.state, base.initial_state)
                         : state_error(r.final_state.body(0), reference, start);
      p.error = r.completed ? p.parts.max() : std::nan("");
      p.steps = r.stats.last_k;
      p.evaluations = r.stats.potential_evaluations;
      p.max_energy_error = r.stats.max_energy_error;
      p.max_linear_momentum_error = r.stats.max_linear_momentum_error;
      const double l0 = r.stats.momentum0.norm();
      p.max_angular_momentum_error = l0 > 0 ? r.stats.max_momentum_error / l0 : r.stats.max_momentum_error;
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
    if (m.time_transformed) {
      // Over the same span, long_steps h, with epsilon = e h: the fixed step's far from the sources, where
      // g = 1, and shorter where the dynamics is fast. Not equal cost then (a closer match, epsilon scaled
      // by the mean g of a shorter run, takes steps far out larger than the fixed step's, which the body's
      // own spin may not allow): comparison.md says how many evaluations it took.
      sc.integrator.duration = static_cast<double>(opt.long_steps) * h;
      sc.integrator.steps = adaptive_max_steps(sc.integrator.duration, sc.integrator.step);
    }
    // The long layout (a [[bodies]] scenario's default): one row per body and output step.
    const TrajectoryLayout layout = base.layout == RowLayout::long_format ? scenario_layout(sc) : TrajectoryLayout{};
    MemorySink sink(2100 * layout.rows_per_step(), layout);
    const SimulationResult r = simulate(sc, sink);
    LongRun& L = long_runs[m];
    L.h = sc.integrator.step;
    L.completed = r.completed;
    L.failure = r.error;
    L.wall = r.wall_seconds;
    L.steps = r.stats.last_k;
    L.last_t = r.stats.last_t;
    L.evaluations = r.stats.potential_evaluations;
    L.max_energy_error = r.stats.max_energy_error;
    L.max_quat = r.stats.max_quat_error;
    const double l0 = r.stats.momentum0.norm();
    L.max_rel_momentum = l0 > 0 ? r.stats.max_momentum_error / l0 : r.stats.max_momentum_error;
    const std::vector<double> rows = sink.take();
    if (base.layout == RowLayout::single_body) {
      for (std::size_t i = 0; i + trajectory_columns <= rows.size(); i += trajectory_columns)
        L.rows.insert(L.rows.end(), {rows[i], rows[i + 15], rows[i + 16], rows[i + 20]});
    } else {
      // Per output step: t, the system's energy error and |L - L0| (every body's row holds them), the
      // largest ||q_a| - 1| of its bodies (bodies_trajectory_header's columns 0, 17, 25 and 15).
      const auto columns = static_cast<std::size_t>(layout.columns);
      const std::size_t step_values = columns * base.bodies();
      for (std::size_t i = 0; i + step_values <= rows.size(); i += step_values) {
        double dq = 0;
        for (std::size_t a = 0; a < base.bodies(); ++a)
          if (std::abs(rows[i + a * columns + 15]) >= std::abs(dq)) dq = rows[i + a * columns + 15];
        L.rows.insert(L.rows.end(), {rows[i], rows[i + 17], dq, rows[i + 25]});
      }
    }
    L.final_energy_error = L.rows.size() >= 4 ? L.rows[L.rows.size() - 3] : std::nan("");
  }

  // Files. The timing columns are the only ones that change from one comparison to the next.
  std::string wp =
      "method,h,steps,potential_evaluations,wall_seconds,wall_seconds_q25,wall_seconds_q75,timing_repeats,error,"
      "position_error,attitude_error_rad,momentum_error,angular_velocity_error,max_abs_energy_error,completed" +
      std::string(system ? ",max_relative_linear_momentum_error,max_relative_angular_momentum_error\n" : "\n");
  for (const MethodChoice& m : opt.methods)
    for (const LadderPoint& p : ladder[m]) {
      wp += fmt::format("{},{},{},{},{},{},{},{},{},{},{},{},{},{},{}", m.name(), json_number(p.h), p.steps,
                        p.evaluations, json_number(p.wall.median), json_number(p.wall.q25),
                        json_number(p.wall.q75), p.wall.repeats, json_number(p.error),
                        json_number(p.completed ? p.parts.position : std::nan("")),
                        json_number(p.completed ? p.parts.attitude : std::nan("")),
                        json_number(p.completed ? p.parts.momentum : std::nan("")),
                        json_number(p.completed ? p.parts.angular_velocity : std::nan("")),
                        json_number(p.max_energy_error), p.completed ? "true" : "false");
      if (system)
        wp += fmt::format(",{},{}", json_number(p.max_linear_momentum_error), json_number(p.max_angular_momentum_error));
      wp += "\n";
    }
  write_file_atomically((fs::path(dir) / "work_precision.csv").string(), wp);
  std::string lt = "method,t,energy_error,quat_norm_error,momentum_error\n";
  for (const MethodChoice& m : opt.methods) {
    const auto& rows = long_runs[m].rows;
    for (std::size_t i = 0; i + 4 <= rows.size(); i += 4)
      lt += fmt::format("{},{},{},{},{}\n", m.name(), json_number(rows[i]), json_number(rows[i + 1]),
                        json_number(rows[i + 2]), json_number(rows[i + 3]));
  }
  write_file_atomically((fs::path(dir) / "long_time.csv").string(), lt);
  if (system)
    write_file_atomically(
        (fs::path(dir) / "reference.json").string(),
        fmt::format("{{\n  \"method\": \"lgvi:8{}\",\n  \"t\": {},\n  \"h_ref\": {},\n  \"change_on_halving\": {},\n"
                    "  \"tolerance\": {},\n  \"tolerance_met\": {}\n}}\n",
                    transformed ? "+tt" : "", json_number(T), json_number(system_reference.h), json_number(system_reference.change),
                    json_number(kReferenceTolerance), system_reference.met ? "true" : "false"));

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
      "long_max_relative_momentum_error,long_completed" +
      std::string(system ? ",max_abs_energy_error_at_h_min,max_relative_linear_momentum_error_at_h_min,"
                           "max_relative_angular_momentum_error_at_h_min,not_applicable\n"
                         : "\n");
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
  const int finest = 1 << (opt.ladder - 1);
  const std::string error_text =
      system
          ? fmt::format(
                "The reference is lgvi composed to order 8 (Kahan & Li's 15 stages{}) at h_ref = {:.6g}, the step at "
                "which halving changes the final state by {:.3e} in the error below ({}; reference.json). Error = "
                "the largest, over the bodies, of |x_a - x_a,ref| / L (L = the largest distance of a body from the "
                "centre of mass, at t = 0 or in the reference), the attitude angle of R_a,ref^T R_a (rad), "
                "|p_a - p_a,ref| / max_b |p_b| and |w_a - w_a,ref| / max_b |w_b| (the scales over t = 0 and the "
                "reference; absolute where a scale is 0); the parts are in work_precision.csv and comparison.csv, "
                "with the system's energy error max |E - E0| and its momentum errors max |P - P0| / sum |p_a0|, "
                "max |L - L0| / |L0| over [0, T].\n",
                transformed ? "; adaptive, +tt: h_ref is its epsilon, the run ending at T" : "", system_reference.h, system_reference.change,
                system_reference.met
                    ? fmt::format("tolerance {:.0e}, met", kReferenceTolerance)
                    : fmt::format("the tolerance {:.0e} is below the round-off accumulated over this run; the "
                                  "change is the reference's accuracy",
                                  kReferenceTolerance))
          : std::string("Error = the largest of "
                        "|x - x_ref| / max(|x_ref|, |x0|), the attitude angle of R_ref^T R (rad), |p - p_ref| / "
                        "max(|p_ref|, |p0|) and |w - w_ref| / max(|w_ref|, |w0|) (absolute where the scale is 0): "
                        "dimensionless, comparable across problems; the parts are in work_precision.csv and "
                        "comparison.csv.\n");
  // A system's table adds the per-body position error and the system's energy error at the finest step.
  const std::string position_column = system ? fmt::format("position error at h/{} | ", finest) : std::string();
  const std::string energy_column =
      system ? fmt::format("max abs energy error over [0, T] at h/{} | ", finest) : std::string();
  const int columns = system ? 13 : 11;
  std::string adaptive_note;
  for (const MethodChoice& m : runnable) {
    if (!m.time_transformed) continue;
    const LongRun& L = long_runs[m];
    adaptive_note += fmt::format("{}{}: epsilon {:.4g}, {} evaluations", adaptive_note.empty() ? "" : "; ", m.name(),
                                 L.h, L.evaluations);
  }
  if (!adaptive_note.empty())
    adaptive_note = fmt::format(
        "The adaptive LGVI (+tt, time_transform = \"potential\"): h is its fictitious-time step epsilon (the "
        "physical step adapts, dt = epsilon g(-V)); its ladder runs end at t = T exactly (exact_finish). Its long "
        "run spans the same time with epsilon = e h, the fixed step's where g = 1, and takes more evaluations where "
        "its step shrinks (not equal cost: a fixed step takes {} + 1 over the whole span): {}.\n",
        opt.long_steps, adaptive_note);
  std::string md = fmt::format(
      "# Comparison on `{}`\n\nWork-precision: steps h = {} ... {} to t = {} against {}. {}"
      "Observed order: from the finest pair of steps whose errors lie in [1e-10, 0.1].\n"
      "Timings: after an untimed first run, each run repeated until the repeats add up to {} s (at least {}); "
      "median [first quartile, third quartile]; \"within noise\" where the quartile intervals overlap.\n"
      "{}; {} steps of h.\n{}\n"
      "| method | {}/step | observed order | error at h | error at h/{} | {}attitude error at h/{} (rad) | {}"
      "ns/step, median [quartiles] | vs lgvi | long: max abs energy error | long: max abs(abs(q) - 1) | long: max rel. {} |\n"
      "|---|{}\n",
      base.name, h0, h_min, T, reference_name, error_text, opt.timing_budget, kMinRepeats, cost_note, opt.long_steps,
      adaptive_note,
      free_body ? "stages" : "evaluations", finest, position_column, finest, energy_column, momentum_column,
      [&] {
        std::string separator;
        for (int c = 1; c < columns; ++c) separator += "---:|";
        return separator;
      }());
  for (const MethodChoice& m : opt.methods) {
    if (const auto u = unable.find(m); u != unable.end()) {
      // Not run: the reason, in the table and in the CSV's last column.
      csv += m.name();
      for (int c = 1; c < 21; ++c) csv += c == 14 || c == 20 ? ",false" : ",null";
      csv += ",null,null,null," + csv_quoted(u->second) + "\n";
      md += fmt::format("| {} | not applicable: {} |", m.name(), u->second);
      for (int c = 2; c < columns; ++c) md += " - |";
      md += "\n";
      continue;
    }
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
    csv += fmt::format("{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{}", m.name(),
                       json_number(per_step), json_number(order), json_number(pts.front().error),
                       json_number(b.error), part(b.parts.position), part(b.parts.attitude),
                       part(b.parts.momentum), part(b.parts.angular_velocity), json_number(ns.median),
                       json_number(ns.q25), json_number(ns.q75), ns.repeats, json_number(vs),
                       noise ? "true" : "false", json_number(L.h), json_number(L.max_energy_error),
                       json_number(L.final_energy_error), json_number(L.max_quat), json_number(L.max_rel_momentum),
                       L.completed ? "true" : "false");
    csv += system ? fmt::format(",{},{},{},\n", json_number(b.max_energy_error),
                                json_number(b.max_linear_momentum_error), json_number(b.max_angular_momentum_error))
                  : std::string("\n");
    md += fmt::format("| {} | {:.2f} | {:.2f} | {} | {} | {}{} | {}{} | {} | {} | {} | {} |\n", m.name(), per_step,
                      order, fmt_e(pts.front().error), fmt_e(b.error),
                      system ? fmt_e(b.completed ? b.parts.position : std::nan("")) + " | " : std::string(),
                      fmt_e(b.completed ? b.parts.attitude : std::nan("")),
                      system ? fmt_e(b.max_energy_error) + " | " : std::string(), fmt_timing(ns, 1.0, ".0f"),
                      !std::isfinite(vs) ? std::string("-")
                      : noise            ? fmt::format("{:.2f} (within noise)", vs)
                                         : fmt::format("{:.2f}", vs),
                      L.completed ? fmt_e(L.max_energy_error) : fmt::format("failed at t = {}", L.last_t),
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
      if (m.method.traits().free_body_only) continue;
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
