#include "app/show.hpp"

#include "app/summary.hpp"
#include "io/json_io.hpp"

#include <lgvi/error.hpp>

#include <fmt/format.h>

#include <algorithm>
#include <filesystem>
#include <fstream>

namespace lgvi::app {

namespace {

/// The member `key` of `v` if `v` is an object that has one, else nullptr.
const Json* member(const Json* v, const char* key) {
  if (!v || !v->is_object()) return nullptr;
  const auto it = v->find(key);
  return it == v->end() ? nullptr : &*it;
}

std::string text(const Json* v) {
  if (!v) return "-";
  if (v->is_string()) return v->get<std::string>();
  if (v->is_number()) return fmt::format("{:.10g}", v->get<double>());
  if (v->is_boolean()) return v->get<bool>() ? "true" : "false";
  if (v->is_array()) {
    std::string s = "(";
    for (std::size_t i = 0; i < v->size(); ++i) s += (i ? ", " : "") + text(&(*v)[i]);
    return s + ")";
  }
  return "null";
}

double number(const Json* v) { return v && v->is_number() ? v->get<double>() : std::nan(""); }

const Json* path(const Json& root, std::initializer_list<const char*> keys) {
  const Json* v = &root;
  for (const char* k : keys) v = member(v, k);
  return v;
}

}  // namespace

void show_run(const std::string& dir, std::ostream& out) {
  const std::string file = (std::filesystem::path(dir) / "summary.json").string();
  std::ifstream in(file);
  if (!in) throw InvalidInput(file + ": no summary here; is '" + dir + "' a run folder written by lgvi run?");
  // The per-body lists (final_bodies, setup.bodies), where a run keeps them in its summary ([output]
  // body_lists = "summary" beyond 10 000 bodies: about 1 GB at 10^6), are most of it; this reads only
  // their length: their entries are counted and dropped as they are parsed, so that the memory stays
  // that of the rest.
  std::size_t final_bodies = 0;
  bool in_final_bodies = false, in_setup = false, in_setup_bodies = false;
  const Json summary = parse_json_file_stream(in, file, [&](int depth, Json::parse_event_t event, Json& parsed) {
    using Event = Json::parse_event_t;
    if (event == Event::key) {
      if (depth == 1) {
        in_final_bodies = parsed == "final_bodies";
        in_setup = parsed == "setup";
        in_setup_bodies = false;
      }
      if (depth == 2) in_setup_bodies = in_setup && parsed == "bodies";
      return true;
    }
    const bool element = (event == Event::object_end || event == Event::array_end || event == Event::value);
    if (element && depth == 2 && in_final_bodies) {
      ++final_bodies;
      return false;
    }
    return !(element && depth == 3 && in_setup_bodies);
  });
  const auto field = [&summary](const char* key) { return member(&summary, key); };
  const bool completed = text(field("completed")) == "true";
  auto row = [&](const std::string& name, const std::string& value) { out << fmt::format("{:<22} {}\n", name, value); };
  row("run", text(field("scenario")) + (completed ? "  (completed)" : "  (NOT completed)"));
  if (!completed) row("stopped because", text(field("error")));
  const Json* epsilon = path(summary, {"setup", "integrator", "epsilon"});  // adaptive runs only
  if (epsilon)
    row("steps", fmt::format("{}, t = {} of {} (adaptive: step {:.3e} to {:.3e})", text(field("steps")),
                             text(field("last_time")), text(field("duration")), number(field("min_step")),
                             number(field("max_step"))));
  else
    row("steps", fmt::format("{} of {}, t = {}", text(field("steps")), text(field("steps_planned")),
                             text(field("last_time"))));
  const Json* order = path(summary, {"setup", "integrator", "order"});  // composed runs only
  row("method", fmt::format("{}{}, solver {}, {} {}", text(path(summary, {"setup", "integrator", "method"})),
                            order ? " composed to order " + text(order) : std::string(),
                            text(path(summary, {"setup", "integrator", "solver"})),
                            epsilon ? "time_transform \"potential\", epsilon" : "step",
                            epsilon ? text(epsilon) : text(path(summary, {"setup", "integrator", "step"}))));
  row("wall time", fmt::format("{:.4g} s ({:.0f} ns/step)", number(field("wall_seconds")),
                               number(field("ns_per_step"))));
  // With [[forcing]], the energy error is E - E0 - W (W the forcing's work), as summary.json's
  // energy_error_is says: the row names it so, with W at the end.
  const Json* work = field("work");
  const Json* energy_error_is = field("energy_error_is");
  if (energy_error_is && energy_error_is->is_string() && energy_error_is->get<std::string>() == "E - E0 - work" &&
      work && work->is_number())
    row("energy", fmt::format("E0 = {}, max |E - E0 - W| = {:.3e} (W: the {} work, {:.6g} at the end)",
                              text(field("initial_energy")), number(field("max_abs_energy_error")),
                              // Motor torques on reaction wheels alone: no external forcing (momentum_error_is).
                              !field("wheels")               ? "forcing's"
                              : field("momentum_error_is") ? "forcing's and the motors'"
                                                           : "motors'",
                              number(work)));
  else
    row("energy", fmt::format("E0 = {}, max |E - E0| = {:.3e}", text(field("initial_energy")),
                              number(field("max_abs_energy_error"))));
  row("|q| - 1", fmt::format("max {:.3e}", number(field("max_abs_quat_norm_error"))));
  // A momentum this run's dynamics does not conserve (a periodic box, a forcing, an external field):
  // summary.json lists its columns under conserved.changes_not_errors; its row says it is a change.
  const Json* changes = path(summary, {"conserved", "changes_not_errors"});
  const auto is_change = [changes](const char* column) {
    return changes && changes->is_array() && std::find(changes->begin(), changes->end(), column) != changes->end();
  };
  constexpr const char* change_note = " -- a change: this run's dynamics does not conserve it";
  row("angular momentum", fmt::format("L0 = {}, max |L - L0| = {:.3e} (relative {:.3e}){}",
                                      text(field("initial_angular_momentum")), number(field("max_momentum_error")),
                                      number(field("max_relative_momentum_error")),
                                      is_change("max_momentum_error") ? change_note : ""));
  // With more bodies than kBodyListsInSummaryUpTo (or [output] body_lists = "file"), the lists are in a
  // file of their own, which the summary names with their length.
  const Json* lists = field("body_lists");
  const Json* listed = lists ? member(lists, "bodies") : nullptr;
  const Json* lists_file = lists ? member(lists, "file") : nullptr;
  const std::size_t n =
      listed && listed->is_number_unsigned() ? listed->get<std::size_t>() : std::max<std::size_t>(final_bodies, 1);
  if (n > 1) {
    row("bodies", listed ? fmt::format("{} (the set-up and final state of each are in {}, a body a line)", n,
                                       lists_file && lists_file->is_string() ? lists_file->get<std::string>()
                                                                             : kBodyListsFile)
                         : fmt::format("{} (the final state of each is in summary.json, final_bodies)", n));
    row("linear momentum", fmt::format("max |P - P0| / sum |p_a0| = {:.3e}{}", number(field("max_linear_momentum_error")),
                                       is_change("max_linear_momentum_error") ? change_note : ""));
    // Contact episodes, where the run checked for them ([run] on_contact "stop" or "warn").
    const Json* contacts = field("contacts");
    if (contacts && contacts->is_array() && contacts->empty()) row("contacts", "none");
    if (contacts && contacts->is_array() && !contacts->empty()) {
      const Json& c = contacts->front();
      const Json* names = member(&c, "bodies");
      row("contacts", fmt::format("{} episode(s); the first: {} and {}, steps {} to {}, deepest {:.4g} (all in "
                                  "summary.json, contacts)",
                                  text(field("contact_episodes")), names && names->size() == 2 ? text(&(*names)[0]) : "-",
                                  names && names->size() == 2 ? text(&(*names)[1]) : "-", text(member(&c, "first_step")),
                                  text(member(&c, "last_step")), number(member(&c, "max_depth"))));
    }
  }
  row("solver iterations", fmt::format("{:.6g} per {} (max {})", number(field("solver_iterations_mean")),
                                       std::string(n > 1 ? "body and " : "") + (order ? "sub-step" : "step"),
                                       text(field("solver_iterations_max"))));
  if (n > 1) return;  // final, below, is body 0's state
  row("final position", text(path(summary, {"final", "position"})));
  row("final quaternion", text(path(summary, {"final", "quaternion"})) + "  (scalar first)");
  row("final momentum", text(path(summary, {"final", "momentum"})));
  // With reaction wheels w = 2 Pi is the total angular momentum of body and wheels (body axes).
  row(path(summary, {"setup", "body", "wheels"}) ? "final w = 2 Pi" : "final w = 2 J Omega",
      text(path(summary, {"final", "w"})));
}

}  // namespace lgvi::app
