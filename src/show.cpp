#include "show.hpp"

#include "json_reader.hpp"

#include <lgvi/error.hpp>

#include <fmt/format.h>

#include <filesystem>
#include <fstream>
#include <sstream>

namespace lgvi::app {

namespace {

std::string text(const JsonValue* v) {
  if (!v) return "-";
  if (const auto* s = std::get_if<std::string>(&v->v)) return *s;
  if (const auto* d = std::get_if<double>(&v->v)) return fmt::format("{:.10g}", *d);
  if (const auto* b = std::get_if<bool>(&v->v)) return *b ? "true" : "false";
  if (v->is_array()) {
    std::string s = "(";
    const auto& items = *std::get<std::shared_ptr<JsonArray>>(v->v);
    for (std::size_t i = 0; i < items.size(); ++i) s += (i ? ", " : "") + text(&items[i]);
    return s + ")";
  }
  return "null";
}

double number(const JsonValue* v) {
  const auto* d = v ? std::get_if<double>(&v->v) : nullptr;
  return d ? *d : std::nan("");
}

const JsonValue* path(const JsonValue& root, std::initializer_list<const char*> keys) {
  const JsonValue* v = &root;
  for (const char* k : keys) {
    v = v->find(k);
    if (!v) return nullptr;
  }
  return v;
}

}  // namespace

void show_run(const std::string& dir, std::ostream& out) {
  const std::string file = (std::filesystem::path(dir) / "summary.json").string();
  std::ifstream in(file);
  if (!in) throw InvalidInput(file + ": no summary here; is '" + dir + "' a run folder written by lgvi run?");
  std::stringstream ss;
  ss << in.rdbuf();
  JsonValue s;
  try {
    s = parse_json(ss.str());
  } catch (const std::exception& e) {
    throw InvalidInput(file + ": " + e.what());
  }
  const bool completed = text(s.find("completed")) == "true";
  auto row = [&](const std::string& name, const std::string& value) { out << fmt::format("{:<22} {}\n", name, value); };
  row("run", text(s.find("scenario")) + (completed ? "  (completed)" : "  (NOT completed)"));
  if (!completed) row("stopped because", text(s.find("error")));
  row("steps", fmt::format("{} of {}, t = {}", text(s.find("steps")), text(s.find("steps_planned")),
                           text(s.find("last_time"))));
  const JsonValue* order = path(s, {"setup", "integrator", "order"});  // composed runs only
  row("method", fmt::format("{}{}, solver {}, step {}", text(path(s, {"setup", "integrator", "method"})),
                            order ? " composed to order " + text(order) : std::string(),
                            text(path(s, {"setup", "integrator", "solver"})),
                            text(path(s, {"setup", "integrator", "step"}))));
  row("wall time", fmt::format("{:.4g} s ({:.0f} ns/step)", number(s.find("wall_seconds")),
                               number(s.find("ns_per_step"))));
  row("energy", fmt::format("E0 = {}, max |E - E0| = {:.3e}", text(s.find("initial_energy")),
                            number(s.find("max_abs_energy_error"))));
  row("|q| - 1", fmt::format("max {:.3e}", number(s.find("max_abs_quat_norm_error"))));
  row("angular momentum", fmt::format("L0 = {}, max |L - L0| = {:.3e} (relative {:.3e})",
                                      text(s.find("initial_angular_momentum")), number(s.find("max_momentum_error")),
                                      number(s.find("max_relative_momentum_error"))));
  const JsonValue* bodies = s.find("final_bodies");
  const std::size_t n = bodies && bodies->is_array() ? std::get<std::shared_ptr<JsonArray>>(bodies->v)->size() : 1;
  if (n > 1) {
    row("bodies", fmt::format("{} (the final state of each is in summary.json, final_bodies)", n));
    row("linear momentum", fmt::format("max |P - P0| / sum |p_a0| = {:.3e}", number(s.find("max_linear_momentum_error"))));
  }
  row("solver iterations", fmt::format("{:.6g} per {} (max {})", number(s.find("solver_iterations_mean")),
                                       std::string(n > 1 ? "body and " : "") + (order ? "sub-step" : "step"),
                                       text(s.find("solver_iterations_max"))));
  if (n > 1) return;  // final, below, is body 0's state
  row("final position", text(path(s, {"final", "position"})));
  row("final quaternion", text(path(s, {"final", "quaternion"})) + "  (scalar first)");
  row("final momentum", text(path(s, {"final", "momentum"})));
  row("final w = 2 J Omega", text(path(s, {"final", "w"})));
}

}  // namespace lgvi::app
