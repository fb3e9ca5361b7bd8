// The gyrostat step's pieces (the model and the derivation: wheels.hpp): the
// implicit rotation equation with the wheels' momentum, and the motor torque
// commands held between samples.
#pragma once

#include <lgvi/checkpoint_fields.hpp>
#include <lgvi/error.hpp>
#include <lgvi/forcing.hpp>
#include <lgvi/rotation_solver.hpp>
#include <lgvi/s3.hpp>
#include <lgvi/sensors.hpp>
#include <lgvi/wheels.hpp>

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <functional>
#include <limits>
#include <memory>
#include <optional>
#include <string>
#include <utility>
#include <vector>

namespace lgvi {

/// The gyrostat's implicit equation, P(J_s f_v + c) = b with P(u) = f_s u +
/// f_v x u, c = (h/2) h_w and b = (h/4)(w0 + h M0) (the file comment), by
/// Newton's method in the Cayley chart f = (1, u)/s, s = sqrt(1 + |u|^2):
///   r(u) = J_s u + u x J_s u + s (c + u x c) - s^2 b = s^2 (P(J_s f_v + c) - b),
///   dr/du = J_s + hat(u) J_s - hat(J_s u) - s hat(c) + (c + u x c) u^T / s - 2 b u^T.
/// With c = 0 it is the rigid body's equation (RotationEquation's Cayley
/// residual). Stops when |r| <= tolerance (|b| + |c|) s^2 or the update is
/// below tolerance |u|; throws StepFailure when it does not converge.
class GyrostatRotationSolver {
 public:
  GyrostatRotationSolver(const Matrix3<double>& reduced_inertia, SolverOptions options)
      : js_(reduced_inertia), opt_(options) {}

  void solve(const Vector3<double>& b, const Vector3<double>& c, S3d& f, SolveReport& report) const {
    report = {};
    if (!(f.w() > 0.0)) f = S3d();
    Vector3<double> u = f.vec() / f.w();
    const double scale = b.norm() + c.norm();
    for (int it = 0; it < opt_.max_iterations; ++it) {
      const double s2 = 1.0 + u.squaredNorm();
      const double s = std::sqrt(s2);
      const Vector3<double> ju = js_ * u;
      const Vector3<double> cu = c + u.cross(c);
      const Vector3<double> r = ju + u.cross(ju) + s * cu - s2 * b;
      ++report.residual_evaluations;
      if (r.norm() <= opt_.tolerance * scale * s2) {
        f = cayley(u, s);
        return;
      }
      Matrix3<double> d = js_ + S3d::hat(u) * js_ - S3d::hat(ju) - s * S3d::hat(c) + (cu / s) * u.transpose() -
                          2.0 * b * u.transpose();
      const Vector3<double> step = detail::solve_3x3(d, r);
      ++report.iterations;
      if (!step.allFinite()) break;
      u -= step;
      if (step.norm() <= opt_.tolerance * u.norm()) {
        f = cayley(u, std::sqrt(1.0 + u.squaredNorm()));
        return;
      }
    }
    throw StepFailure("the gyrostat's rotation equation did not converge in " + std::to_string(opt_.max_iterations) +
                          " iterations", detail::smaller_step_hint);
  }

  const Matrix3<double>& reduced_inertia() const { return js_; }

 private:
  static S3d cayley(const Vector3<double>& u, double s) { return S3d(1.0 / s, u.x() / s, u.y() / s, u.z() / s); }
  Matrix3<double> js_;
  SolverOptions opt_;
};

/// A motor torque command held between samples (zero-order hold): u(t) =
/// u_i for t_i <= t < t_{i+1}, the first value before t_0 and the last after
/// the last time. A constant is one row. impulse(t0, t1, limit) is the exact
/// integral over [t0, t1] of u clipped to [-limit, limit].
class HeldTorque {
 public:
  HeldTorque() = default;
  static HeldTorque constant(double u) { return HeldTorque({0.0}, {u}); }
  /// Throws InvalidInput unless the times are finite and strictly increasing
  /// and the values finite, with as many values as times (one at least).
  HeldTorque(std::vector<double> t, std::vector<double> u) : t_(std::move(t)), u_(std::move(u)) {
    if (t_.empty() || t_.size() != u_.size()) throw InvalidInput("table: one torque per time, one row at least");
    for (std::size_t i = 0; i < t_.size(); ++i) {
      if (!std::isfinite(t_[i]) || !std::isfinite(u_[i]))
        throw InvalidInput("table: row " + std::to_string(i + 1) + " is not finite");
      if (i > 0 && !(t_[i] > t_[i - 1]))
        throw InvalidInput("table: times must be strictly increasing (row " + std::to_string(i + 1) + ")");
    }
  }

  /// The commanded torque at t.
  double at(double t) const { return u_[segment(t)]; }

  /// The integral of u, clipped to [-limit, limit], over [t0, t1] (t0 <= t1), summed segment by
  /// segment: a command held over the whole step is u h, bit for bit.
  double impulse(double t0, double t1, double limit = std::numeric_limits<double>::infinity()) const {
    double total = 0.0;
    double a = t0;
    for (std::size_t i = segment(t0); a < t1; ++i) {
      const double end = i + 1 < t_.size() ? std::min(t1, t_[i + 1]) : t1;
      total += std::clamp(u_[i], -limit, limit) * (end - a);
      a = end;
    }
    return total;
  }

 private:
  /// The row in force at t: the last i with t_i <= t (0 before the first).
  std::size_t segment(double t) const {
    std::size_t i = 0;
    while (i + 1 < t_.size() && t_[i + 1] <= t) ++i;
    return i;
  }
  std::vector<double> t_{0.0};
  std::vector<double> u_{0.0};
};

/// Attitude control through a body's reaction wheels: the attitude controller's law (AttitudeControl,
/// forcing.hpp: PD toward a target quaternion, |M| limited) on the gyrostat's own rate, sampled at t =
/// n period (every step for period 0) and held, its body torque M distributed over the wheels as motor
/// torques u = -A^+ M (A = [a_1 ... a_k], A^+ = A^T (A A^T)^-1, the least-norm split), which the step
/// then clips to each wheel's limits. A copy sampled on the same states gives the same commands bit for
/// bit (the recorder's columns). Needs axes that span space (checked: InvalidInput). With sensors
/// (set_sensors, sensors.hpp) the law sees their readings at each sample instead of the true state. The
/// body torque may instead be a table of time (set_torque_table) or a law of one's own (set_law).
class WheelAttitudeControl {
 public:
  WheelAttitudeControl() = default;
  WheelAttitudeControl(const AttitudeControl& law, const Wheels& wheels) : law_(law) {
    Eigen::Matrix<double, 3, Eigen::Dynamic> a(3, static_cast<Eigen::Index>(wheels.size()));
    for (std::size_t i = 0; i < wheels.size(); ++i) a.col(static_cast<Eigen::Index>(i)) = wheels[i].axis;
    const Matrix3<double> gram = a * a.transpose();
    Eigen::LLT<Matrix3<double>> llt(gram);
    if (wheels.size() < 3 || llt.info() != Eigen::Success || gram.determinant() < 1e-12 * std::pow(gram.trace(), 3))
      throw InvalidInput("the wheels' axes do not span space: three directions at least are needed to turn the body "
                         "about any axis");
    split_ = -(a.transpose() * gram.inverse());
    command_.assign(wheels.size(), 0.0);
  }
  /// The same with a user's distribution matrix D (one row of 3 per wheel): u = D M. The body then
  /// receives -A D M, which must be M: -A D = I to 1e-9 (InvalidInput otherwise), e.g. a split that
  /// leaves a failed wheel out, or one that also manages the wheels' null space.
  WheelAttitudeControl(const AttitudeControl& law, const Wheels& wheels,
                       const Eigen::Matrix<double, Eigen::Dynamic, 3>& distribution)
      : WheelAttitudeControl(law, wheels) {
    if (static_cast<std::size_t>(distribution.rows()) != wheels.size() || !distribution.allFinite())
      throw InvalidInput("the distribution matrix needs one row of 3 finite numbers per wheel (" +
                         std::to_string(wheels.size()) + " rows)");
    Eigen::Matrix<double, 3, Eigen::Dynamic> a(3, static_cast<Eigen::Index>(wheels.size()));
    for (std::size_t i = 0; i < wheels.size(); ++i) a.col(static_cast<Eigen::Index>(i)) = wheels[i].axis;
    const Matrix3<double> received = -(a * distribution);
    const double off = (received - Matrix3<double>::Identity()).cwiseAbs().maxCoeff();
    if (!(off <= 1e-9))
      throw InvalidInput("the body receives -A D M from the motor torques u = D M (A the wheels' axes): -A D must be "
                         "the identity, and differs from it by " + std::to_string(off) + " here");
    split_ = distribution;
  }
  /// The law reads these sensors at its samples (n = the sample's number): a sampled law only (period >
  /// 0; InvalidInput otherwise).
  void set_sensors(AttitudeSensors sensors) {
    if (!(law_.period > 0.0))
      throw InvalidInput("sensors are read at the controller's samples: give the attitude controller a period");
    sensors_ = std::move(sensors);
  }
  const std::optional<AttitudeSensors>& sensors() const { return sensors_; }

  /// A control law of one's own in place of the PD law: the body torque M = law(t, what the law sees (the
  /// sensors' readings, or the truth), the wheels' speeds relative to the body), body axes, then scaled
  /// down to max_torque and split over the wheels as the PD law's. Copies share the value it returned at
  /// the last sample time: the recorder's copy, sampling the same states, does not call it again, so a
  /// law with a state of its own (an integral term) is called once per sample.
  using Law = std::function<Vector3<double>(double, const AttitudeMeasurement&, const std::vector<double>&)>;
  /// A commanded body torque of its own in place of the PD law: M = table(t) (body axes) at each sample,
  /// scaled down to max_torque and split over the wheels (open loop: the state is not read).
  void set_torque_table(Profile table) { torque_table_ = std::move(table); }
  void set_law(Law law) { custom_ = std::make_shared<CustomLaw>(CustomLaw{std::move(law)}); }
  bool has_custom_law() const { return custom_ != nullptr; }

  /// At a step from t: samples when t reaches the next sample time (the state's attitude q and rate
  /// omega, or the sensors' readings of them; the wheels' speeds relative to the body for a law of one's
  /// own). Returns whether it sampled.
  bool sample(double t, const S3d& q, const Vector3<double>& omega, const std::vector<double>& wheel_speeds) {
    std::int64_t n = 0;
    if (law_.period > 0.0) {
      const double slot = t / law_.period + 1e-9;
      if (sampled_ && slot < static_cast<double>(next_sample_)) return false;
      n = static_cast<std::int64_t>(std::floor(slot));
      next_sample_ = n + 1;
    }
    sampled_ = true;
    measured_ = sensors_ ? sensors_->measure(n, q, omega) : AttitudeMeasurement{q, omega, Vector3<double>::Zero()};
    Vector3<double> m;
    if (custom_) {
      if (!(custom_->valid && custom_->t == t)) {
        Vector3<double> asked = custom_->law(t, measured_, wheel_speeds);
        if (!asked.allFinite()) throw StepFailure("the control law returned a torque that is not finite", "check the law");
        if (asked.norm() > law_.max_torque) asked *= law_.max_torque / asked.norm();
        custom_->torque = asked;
        custom_->t = t;
        custom_->valid = true;
      }
      m = custom_->torque;
    } else if (torque_table_) {
      m = torque_table_->at(t);
      if (m.norm() > law_.max_torque) m *= law_.max_torque / m.norm();
    } else {
      m = law_.torque_for(measured_.q, measured_.omega);
    }
    const Eigen::VectorXd u = split_ * m;
    for (std::size_t i = 0; i < command_.size(); ++i) command_[i] = u(static_cast<Eigen::Index>(i));
    return true;
  }
  /// Forgets the samples (a run starting anew).
  void reset() {
    sampled_ = false;
    next_sample_ = 0;
    std::fill(command_.begin(), command_.end(), 0.0);
    if (sensors_) sensors_->reset();
    if (custom_) custom_->valid = false;
  }
  /// A checkpoint's fields under `prefix` (checkpoint_fields.hpp): "PREFIX.samples" (whether it has
  /// sampled, the next sample's number), "PREFIX.command" (the held command per wheel) and, with sensors,
  /// theirs under "PREFIX.sensors". A law of one's own (set_law) keeps a state lgvi cannot save: refused
  /// (InvalidInput).
  void save(CheckpointFields& out, const std::string& prefix) const {
    if (custom_) throw InvalidInput("a control law of one's own (Python) cannot be checkpointed: its state is its own");
    out.put_i64(prefix + ".samples", {sampled_ ? 1 : 0, next_sample_});
    out.put_f64(prefix + ".command", command_);
    if (sensors_) sensors_->save(out, prefix + ".sensors");
  }
  /// Restores what save(out, prefix) wrote at the step from time t (InvalidInput, naming the field, for a
  /// field missing or of the wrong size, or one that does not fit this controller at t, e.g. after its
  /// period was changed). A sampled law's next sample is floor(t / period) + 1 once it has been given the
  /// state at t (`sampled_at_t`: the recorder's copy), at most that before (the stepper's).
  void load(const CheckpointFields& in, const std::string& prefix, double t, bool sampled_at_t) {
    const std::vector<std::int64_t>& n = in.i64(prefix + ".samples", 2);
    command_ = in.f64(prefix + ".command", command_.size());
    if (n[0] != 0 && n[0] != 1) throw InvalidInput("checkpoint field '" + prefix + ".samples' is damaged");
    sampled_ = n[0] != 0;
    next_sample_ = n[1];
    if (law_.period > 0.0 && sampled_) {
      const auto next = static_cast<std::int64_t>(std::floor(t / law_.period + 1e-9)) + 1;
      if (next_sample_ < 0 || next_sample_ > next || (sampled_at_t && next_sample_ != next))
        throw InvalidInput("checkpoint field '" + prefix + ".samples' holds the controller's next sample " +
                           std::to_string(next_sample_) + ", which a period of " + std::to_string(law_.period) +
                           " s does not give at t = " + std::to_string(t) + ": was the scenario's period or step "
                           "changed?");
    }
    if (sensors_) {
      sensors_->load(in, prefix + ".sensors");
      if (sensors_->next_sample() > next_sample_)
        throw InvalidInput("checkpoint field '" + prefix + ".sensors.samples' is ahead of the controller's samples");
    }
  }
  /// What the law saw at its last sample (the true state without sensors).
  const AttitudeMeasurement& measured() const { return measured_; }
  /// The motor torque command of each wheel (N m), before the wheels' limits.
  const std::vector<double>& command() const { return command_; }
  const AttitudeControl& law() const { return law_; }

 private:
  AttitudeControl law_;
  Eigen::Matrix<double, Eigen::Dynamic, 3> split_;
  std::vector<double> command_;
  std::optional<AttitudeSensors> sensors_;
  AttitudeMeasurement measured_;
  struct CustomLaw {
    Law law;
    double t = 0.0;  ///< the sample time of `torque`
    Vector3<double> torque = Vector3<double>::Zero();
    bool valid = false;
  };
  std::shared_ptr<CustomLaw> custom_;  ///< shared by copies (see set_law)
  std::optional<Profile> torque_table_;  ///< set_torque_table
  std::int64_t next_sample_ = 0;
  bool sampled_ = false;
};

/// A motor torque command on wheel `wheel` of body `body` (the stepper's set_wheel_torques).
struct WheelTorque {
  std::size_t body = 0;
  std::size_t wheel = 0;
  HeldTorque torque;
};

}  // namespace lgvi
