// A scenario file (TOML) describes one run: body, potential, initial state,
// integrator and output. The reader rejects unknown keys, missing keys, wrong
// types and invalid values with an InvalidInput naming the key.
#pragma once

#include <lgvi/composition.hpp>
#include <lgvi/contact.hpp>
#include <lgvi/forcing.hpp>
#include <lgvi/gyrostat.hpp>
#include <lgvi/rigid_body.hpp>
#include <lgvi/rotation_solver.hpp>
#include <lgvi/state.hpp>
#include <lgvi/system.hpp>

#include "app/method.hpp"
#include "io/formats/format.hpp"

#include <cstdint>
#include <functional>
#include <map>
#include <optional>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

namespace lgvi::app {

// The application is built on the I/O layer (src/io, namespace lgvi::io, below it:
// io names nothing of app, tests/check_library_layers.py) and names its types unqualified.
using namespace lgvi::io;

enum class PotentialKind { None, Central, Uniform, HeavyTop };

struct PotentialSpec {
  PotentialKind kind = PotentialKind::None;
  double mu = 0.0;                                   // central
  bool stop_at_contact = false;                      // central: stop when a ball touches the source
  bool point_masses = false;                         // central: model = "point" (mass + inertia bodies: no torque)
  double j2 = 0.0, reference_radius = 0.0;           // central: oblate source (J2 = 0: a point)
  Vector3<double> pole = Vector3<double>::UnitZ();   // central: the source's axis of symmetry
  Vector3<double> g = Vector3<double>::Zero();     // uniform, heavy-top
  Vector3<double> pivot_to_com = Vector3<double>::Zero();  // heavy-top: chi, body frame
};

struct InteractionDescriptor;  // interactions/registry.hpp

/// The most site types (Ball::type) a scenario may use: a typed pair
/// potential holds a table of types^2 coefficients.
inline constexpr int max_site_types = 256;

/// One pair of site types' coefficients (`[[interaction.pair]]`, or mixed
/// from the types' own), types first <= second.
struct TypePairSpec {
  int first = 1, second = 1;
  std::map<std::string, double, std::less<>> numbers;  ///< e.g. epsilon, sigma
  bool mixed = false;  ///< mixed from (first, first) and (second, second) rather than given
};

/// Mutual interactions between the bodies (`[interaction]`): which one (its
/// descriptor, interactions/registry.hpp; null: none) and its keys as read,
/// defaults filled in.
struct InteractionSpec {
  const InteractionDescriptor* descriptor = nullptr;
  std::map<std::string, double, std::less<>> numbers;      ///< e.g. G, epsilon, sigma, cutoff, skin
  std::map<std::string, std::string, std::less<>> words;  ///< e.g. model
  /// Per pair of site types, every pair first <= second of the system's
  /// types; empty where the interaction has one set of coefficients for all.
  std::vector<TypePairSpec> type_pairs;
  bool none() const { return descriptor == nullptr; }
  /// A key the descriptor has read (std::logic_error otherwise).
  double number(std::string_view key) const;
  const std::string& word(std::string_view key) const;
};

/// [interaction] kind: "none" or the descriptor's kind.
std::string interaction_kind(const InteractionSpec& spec);

/// What a run does when two bodies overlap (`[run] on_contact`): the model
/// has no contact forces, so from there on it does not describe what it
/// simulates.
enum class OnContact {
  Stop,   ///< "stop" (default): stop at the first step with an overlap, completed: false
  Warn,   ///< "warn": record every contact episode in the summary and go on
  Ignore  ///< "ignore": no check during the run (the default for Lennard-Jones systems and single bodies)
};

/// [integrator] time_transform: "none" (a fixed step) or "potential" (the
/// adaptive LGVI, time_transformed.hpp).
enum class TimeTransform { None, Potential };

struct IntegratorSpec {
  Method method;  ///< default: "lgvi"
  SolverOptions solver;
  /// [integrator] order / composition: the sub-steps of a composed step
  /// (one stage, gamma = 1, by default: the method's own step).
  CompositionTable composition;
  /// The step h; with a time transformation, the fictitious-time step
  /// epsilon (the physical step adapts).
  double step = 0.0;
  double duration = 0.0;
  /// ceil(duration / step), computed on reading; with a time transformation
  /// the most steps the run may take (max_steps): it ends with the first step
  /// that reaches `duration`.
  std::int64_t steps = 0;
  TimeTransform time_transform = TimeTransform::None;
  double monitor_scale = 0.0;  ///< time_transform: c of the monitor; 0: |V| at the start
  /// time_transform: the last step is shortened so that the run ends at
  /// t = duration exactly (time_transformed.hpp: finish_time).
  bool exact_finish = false;
  bool adaptive() const { return time_transform != TimeTransform::None; }
  /// Whether a run that has reached step k at time t is at its end: a fixed
  /// step's after `steps` steps, an adaptive run's with the first step that
  /// reaches `duration` (its `steps`, max_steps, then ends it as a failure;
  /// with exact_finish that step ends at `duration`).
  bool ends(std::int64_t k, double t) const { return adaptive() ? t >= duration : k >= steps; }
};

/// Where a [[bodies]] run writes its lists of bodies (each body's set-up and
/// final state): in summary.json (setup.bodies, final_bodies), or one body a
/// line in bodies.jsonl beside it, the summary naming the file and its length
/// ([output] body_lists; by default the summary up to kBodyListsInSummaryUpTo
/// bodies, about 0.9 kB each, and the file beyond).
enum class BodyLists { summary, file };
inline constexpr std::size_t kBodyListsInSummaryUpTo = 10000;

struct Scenario {
  std::string name;  ///< the file's stem
  std::string source;  ///< the file it was read from (what parse_scenario was given): refusals start with it
  System system;     ///< the bodies, in scenario order (one for a [body] scenario)
  PotentialSpec potential;  ///< the external field, acting on every body
  InteractionSpec interaction;
  ForcingSet forcing;  ///< [[forcing]]: wrenches besides the potential (empty: none)
  /// [[forcing]] kind = "wheel-torque": motor torques on the body's reaction wheels ([[body.wheel]],
  /// gyrostat.hpp), internal torques (not in `forcing`).
  std::vector<WheelTorque> wheel_torques;
  /// [[forcing]] kind = "attitude-control" with actuator = "wheels": the controller turning the body with its
  /// reaction wheels (gyrostat.hpp); none otherwise.
  std::optional<WheelAttitudeControl> wheel_control;
  /// The targets of the [[forcing]] kind = "attitude-control" entries (either actuator), in their order:
  /// what an ensemble's pointing error is measured from.
  std::vector<S3d> attitude_targets;
  SystemState initial_state;
  /// Written with [[bodies]] (or imported: [import]) rather than with [body]
  /// + [initial]: what the summary (setup.bodies) and the messages
  /// ("bodies[a]") name the bodies by.
  bool many_body_form = false;
  /// [output] layout: by default the single-body layout for a [body]
  /// scenario, the long one for [[bodies]].
  RowLayout layout = RowLayout::single_body;
  int threads = 0;  ///< [run] threads; 0: all cores
  OnContact on_contact = OnContact::Ignore;  ///< [run] on_contact, or its default for this scenario
  bool on_contact_given = false;             ///< whether [run] on_contact was given
  IntegratorSpec integrator;
  std::int64_t output_every = 1;
  TrajectoryFormat output_format;  ///< [output] format (default csv)
  BodyLists body_lists = BodyLists::summary;  ///< [output] body_lists, or its default for this scenario
  std::string source_text;  ///< the TOML text it was read from
  bool imported = false;    ///< its bodies come from a data file ([import])
  FileIds file_ids;         ///< an [import]'s (empty without one)

  /// Body 0 and its initial state: the body of a single-body scenario.
  const RigidBody& body() const { return system.body(0); }
  RigidBodyState initial() const { return initial_state.body(0); }
  std::size_t bodies() const { return system.size(); }
};

/// What a scenario's dynamics conserve, by its symmetries (Noether): the
/// total angular momentum about the origin with no field or a point source
/// (mutual forces between bodies keep it too), only its component along the
/// pole with an oblate (J2) source, neither in a uniform field, on a pivot or
/// under a forcing other than pair damping (internal); the linear momentum
/// with no field and no forcing but pair damping; the
/// energy always (E - E0 - W, W the forcing's work, under a forcing). Where a
/// momentum is not conserved, its "error" columns measure a change, not an
/// error of the method.
struct ConservationLaws {
  enum class Angular { Conserved, AlongPole, NotConserved };
  bool forced = false;  ///< energy_error is E - E0 - W
  Angular angular_momentum = Angular::NotConserved;
  bool linear_momentum = false;
};
ConservationLaws conservation_laws(const Scenario& sc);

/// An adaptive run's max_steps when not given: 100 duration / epsilon (the physical step 100 times
/// below epsilon on average: a run that is stuck), at least 1; nullopt beyond 2^53.
std::optional<std::int64_t> default_max_steps(double duration, double epsilon);

/// Why the adaptive LGVI (time_transform = "potential") cannot run a scenario: its
/// monitor reads U = -V as a measure of closeness, so it needs an attraction (a
/// central field, mutual gravity) and nothing whose V can be positive or that does
/// work outside the Hamiltonian. `key` is the scenario key at fault.
struct TimeTransformRefusal {
  std::string key, reason;
};
std::optional<TimeTransformRefusal> time_transform_refusal(const PotentialSpec& potential,
                                                          const InteractionSpec& interaction, bool forced);

/// Whether a body given by mass + inertia feels a central field's
/// gravity-gradient term ([potential] kind = "central" without model =
/// "point"): what lgvi before that model ran as a point mass, so that a run or
/// an ensemble begun by such an lgvi must not be continued with it.
bool has_gravity_gradient_body(const Scenario& sc);

/// Reads and validates a scenario file. Throws InvalidInput with a message
/// "FILE: KEY: what is wrong; how to fix it".
Scenario read_scenario(const std::string& path);

/// The same, from TOML text (`name` is used in messages and as the name).
Scenario parse_scenario(const std::string& toml_text, const std::string& name);

const char* to_string(PotentialKind k);
const char* to_string(OnContact c);

/// What a contact's reach (Contact::reach) is, for messages: "radii 0.3 +
/// 0.1" for two spheres (balls; a point has radius 0), else the centre
/// distance at which the two pieces, named by their semi-axes, radius or as
/// a point, would just touch along their line.
std::string describe_reach(const System& system, const Contact& c);
const char* to_string(Method m);

}  // namespace lgvi::app
