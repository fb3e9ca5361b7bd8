#include "run.hpp"

#include "output.hpp"

#include <lgvi/integrate.hpp>
#include <lgvi/lgvi.hpp>
#include <lgvi/potential.hpp>

#include <fmt/format.h>

#include <chrono>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <memory>
#include <filesystem>
#include <iostream>
#include <spawn.h>
#include <sys/wait.h>
#include <variant>

extern char** environ;

namespace lgvi::app {

namespace fs = std::filesystem;

namespace {

using AnyPotential = std::variant<NoPotential, CentralGravity, UniformGravity>;

AnyPotential make_potential(const Scenario& s) {
  switch (s.potential.kind) {
    case PotentialKind::Central: return CentralGravity(s.body, s.potential.mu);
    case PotentialKind::Uniform: return UniformGravity(s.body, s.potential.g);
    case PotentialKind::None: break;
  }
  return NoPotential{};
}

/// Diagnostics over every step (written or not) and the rows written.
struct Recorder {
  const Scenario& scenario;
  CsvWriter& csv;
  double energy0 = 0.0;
  Vector3<double> momentum0 = Vector3<double>::Zero();
  double max_energy_error = 0.0, max_quat_error = 0.0, max_momentum_error = 0.0;
  std::int64_t iterations_total = 0, steps_solved = 0;
  int iterations_max = 0;
  double last_t = 0.0;
  std::int64_t last_k = 0;
  bool observed = false;  ///< at least the initial state was evaluated and recorded

  void operator()(const StepInfo& i) {
    const RigidBodyState& s = i.state;
    const double energy = total_energy(s, scenario.body, i.evaluation);
    const Vector3<double> L = angular_momentum(s);
    if (i.k == 0) {
      energy0 = energy;
      momentum0 = L;
    } else {
      iterations_total += i.solve.iterations;
      iterations_max = std::max(iterations_max, i.solve.iterations);
      ++steps_solved;
    }
    const double de = energy - energy0, dq = s.q.norm_error(), dl = (L - momentum0).norm();
    max_energy_error = std::max(max_energy_error, std::abs(de));
    max_quat_error = std::max(max_quat_error, std::abs(dq));
    max_momentum_error = std::max(max_momentum_error, dl);
    last_t = i.t;
    last_k = i.k;
    observed = true;
    if (i.k % scenario.output_every == 0 || i.k == scenario.integrator.steps) {
      const auto& q = s.q.quaternion();
      const double row[trajectory_columns] = {i.t,    s.x.x(), s.x.y(), s.x.z(), q.w(),  q.x(),  q.y(),
                                              q.z(),  s.p.x(), s.p.y(), s.p.z(), s.w.x(), s.w.y(), s.w.z(),
                                              energy, de,      dq,      L.x(),   L.y(),   L.z(),   dl};
      csv.row(row);
    }
  }
};

std::vector<double> to_vector(const Eigen::Ref<const Eigen::VectorXd>& v) { return {v.data(), v.data() + v.size()}; }

JsonObject scenario_json(const Scenario& s) {
  JsonObject body;
  body.number("mass", s.body.mass());
  std::string inertia = "[";
  for (int i = 0; i < 3; ++i) {
    inertia += (i ? ", [" : "[") + json_number(s.body.inertia()(i, 0)) + ", " + json_number(s.body.inertia()(i, 1)) +
               ", " + json_number(s.body.inertia()(i, 2)) + "]";
  }
  body.raw("inertia", inertia + "]");
  std::string balls = "[";
  for (std::size_t i = 0; i < s.body.balls().size(); ++i) {
    const Ball& b = s.body.balls()[i];
    balls += fmt::format("{}{{\"position\": [{}, {}, {}], \"mass\": {}, \"radius\": {}}}", i ? ", " : "",
                         json_number(b.position.x()), json_number(b.position.y()), json_number(b.position.z()),
                         json_number(b.mass), json_number(b.radius));
  }
  body.raw("balls", balls + "]");
  JsonObject pot;
  pot.string("kind", to_string(s.potential.kind));
  if (s.potential.kind == PotentialKind::Central) pot.number("mu", s.potential.mu);
  if (s.potential.kind == PotentialKind::Uniform) pot.array("g", to_vector(s.potential.g));
  JsonObject integ;
  integ.string("method", to_string(s.integrator.method))
      .string("solver", to_string(s.integrator.solver.kind))
      .number("step", s.integrator.step)
      .number("tolerance", s.integrator.solver.tolerance)
      .integer("max_iterations", s.integrator.solver.max_iterations)
      .integer("predictor_order", s.integrator.solver.predictor_order);
  JsonObject o;
  o.object("body", body).object("potential", pot).object("integrator", integ).integer("output_every", s.output_every);
  return o;
}

JsonObject state_json(const RigidBodyState& s) {
  JsonObject o;
  o.array("position", to_vector(s.x))
      .array("quaternion", {s.q.w(), s.q.quaternion().x(), s.q.quaternion().y(), s.q.quaternion().z()})
      .array("momentum", to_vector(s.p))
      .array("w", to_vector(s.w));
  return o;
}

/// Folder holding the `lgvi` Python package (for the figures).
std::string python_dir() {
  if (const char* env = std::getenv("LGVI_PYTHON_DIR")) return env;
  std::error_code ec;
  if (fs::exists(fs::path(LGVI_SOURCE_PYTHON_DIR) / "lgvi" / "plot.py", ec)) return LGVI_SOURCE_PYTHON_DIR;
  return LGVI_INSTALLED_PYTHON_DIR;
}

}  // namespace

void draw_figures(const std::string& run_dir) {
  const char* py_env = std::getenv("LGVI_PYTHON");
  const std::string python = py_env ? py_env : "/usr/bin/python3";
  std::string pythonpath = python_dir();
  if (const char* old = std::getenv("PYTHONPATH")) pythonpath += std::string(":") + old;
  std::vector<std::string> env_strings{"PYTHONPATH=" + pythonpath, "MPLBACKEND=Agg"};
  for (char** e = environ; *e; ++e)
    if (std::strncmp(*e, "PYTHONPATH=", 11) != 0 && std::strncmp(*e, "MPLBACKEND=", 11) != 0) env_strings.emplace_back(*e);
  std::vector<char*> envp;
  for (auto& e : env_strings) envp.push_back(e.data());
  envp.push_back(nullptr);
  std::vector<std::string> args{python, "-m", "lgvi.plot", run_dir};
  std::vector<char*> argv;
  for (auto& a : args) argv.push_back(a.data());
  argv.push_back(nullptr);
  pid_t pid;
  if (posix_spawn(&pid, python.c_str(), nullptr, nullptr, argv.data(), envp.data()) != 0)
    throw std::runtime_error("cannot start " + python + " to draw the figures (install python3-matplotlib, or set "
                             "LGVI_PYTHON; --no-figures skips them)");
  int status = 0;
  waitpid(pid, &status, 0);
  if (!WIFEXITED(status) || WEXITSTATUS(status) != 0)
    throw std::runtime_error("drawing the figures with " + python +
                             " -m lgvi.plot failed (see its message above; --no-figures skips them)");
}

int run_scenario(const Scenario& sc, const RunOptions& opt) {
  const std::string dir = opt.out_dir.empty() ? sc.name : opt.out_dir;
  const fs::path csv_path = fs::path(dir) / "trajectory.csv";
  const fs::path summary_path = fs::path(dir) / "summary.json";
  std::unique_ptr<CsvWriter> csv;
  try {
    fs::create_directories(dir);
    // A summary left by an earlier run must not describe this one.
    fs::remove(summary_path);
    csv = std::make_unique<CsvWriter>(csv_path.string(), trajectory_header, trajectory_columns);
  } catch (const std::exception& e) {
    std::cerr << "lgvi: error: output folder '" << dir << "' cannot be written: " << e.what()
              << "; choose another with --out\n";
    return kBadInput;
  }

  RigidBodyState state = sc.initial;
  Recorder rec{sc, *csv};
  std::string failure;
  AnyPotential potential_variant = make_potential(sc);
  const auto start = std::chrono::steady_clock::now();
  try {
    std::visit(
        [&](auto& potential) {
          using P = std::decay_t<decltype(potential)>;
          if (sc.integrator.method == Method::Hamiltonian) {
            LieGroupVariationalIntegrator<P> stepper(sc.body, potential, sc.integrator.step, sc.integrator.solver);
            integrate_n_steps(stepper, state, 0.0, sc.integrator.steps, rec);
          } else {
            LagrangianLieGroupVariationalIntegrator<P> stepper(sc.body, potential, sc.integrator.step,
                                                                sc.integrator.solver);
            integrate_n_steps(stepper, state, 0.0, sc.integrator.steps, rec);
          }
        },
        potential_variant);
  } catch (const IntegrationFailure& e) {
    failure = e.what();
  }
  try {
    csv->close();
  } catch (const std::exception& e) {
    failure = failure.empty() ? std::string(e.what()) : failure;
  }
  const double wall = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();

  JsonObject summary;
  summary.string("scenario", sc.name)
      .boolean("completed", failure.empty())
      .string("error", failure)
      .integer("steps", rec.last_k)
      .number("duration", sc.integrator.step * static_cast<double>(sc.integrator.steps))
      .number("last_time", rec.last_t)
      .number("wall_seconds", wall)
      .number("ns_per_step", rec.last_k > 0 ? wall * 1e9 / static_cast<double>(rec.last_k) : 0.0)
      .number("initial_energy", rec.observed ? rec.energy0 : std::nan(""))
      .array("initial_angular_momentum", to_vector(rec.momentum0))
      .number("max_abs_energy_error", rec.max_energy_error)
      .number("max_abs_quat_norm_error", rec.max_quat_error)
      .number("max_momentum_error", rec.max_momentum_error)
      .number("max_relative_momentum_error",
              rec.momentum0.norm() > 0 ? rec.max_momentum_error / rec.momentum0.norm() : rec.max_momentum_error)
      .number("solver_iterations_mean",
              rec.steps_solved ? static_cast<double>(rec.iterations_total) / static_cast<double>(rec.steps_solved) : 0.0)
      .integer("solver_iterations_max", rec.iterations_max)
      .object("final", state_json(state))
      .object("setup", scenario_json(sc));
  try {
    write_file_atomically(summary_path.string(), summary.str() + "\n");
  } catch (const std::exception& e) {
    std::cerr << "lgvi: error: " << e.what() << "\n";
    return kRunFailed;
  }
  if (!failure.empty()) {
    std::cerr << "lgvi: error: " << failure << "\n";
    if (rec.observed)
      std::cerr << "lgvi: the trajectory up to t = " << rec.last_t << " is in " << csv_path.string()
                << "; summary.json says \"completed\": false\n";
    else
      std::cerr << "lgvi: no state could be evaluated, " << csv_path.string()
                << " holds only its header; summary.json says \"completed\": false\n";
    return kRunFailed;
  }
  if (!opt.quiet)
    std::cout << fmt::format(
        "{}: {} steps in {:.3f} s ({:.0f} ns/step); max |dE| = {:.3e}, max ||q|-1| = {:.3e}, max |dL|/|L0| = {:.3e}; "
        "output in {}\n",
        sc.name, rec.last_k, wall, rec.last_k ? wall * 1e9 / static_cast<double>(rec.last_k) : 0.0,
        rec.max_energy_error, rec.max_quat_error,
        rec.momentum0.norm() > 0 ? rec.max_momentum_error / rec.momentum0.norm() : rec.max_momentum_error, dir);
  if (opt.figures) {
    try {
      draw_figures(dir);
    } catch (const std::exception& e) {
      std::cerr << "lgvi: error: the run completed and its files are written, but " << e.what() << "\n";
      return kRunFailed;
    }
  }
  return kSuccess;
}

}  // namespace lgvi::app
