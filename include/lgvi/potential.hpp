// Potentials V(x, q): the energy, the inertial force -dV/dx and the body
// torque M, evaluated together (one evaluation per integrator step).
//
// Torque and the paper's F(q) dV/dq. The paper writes the potential's
// rotational derivative as F(q) dV/dq, with dV/dq the gradient of V in
// H = R^4. Along the left-trivialized variation delta q = q (0, eta),
// delta V = (dV/dq)^T F(q)^T eta, while the rotation changes by
// delta R = R hat(2 eta) (the paper's T pi). The body-frame torque M is
// defined by delta V = -M . delta theta for delta R = R hat(delta theta), so
//
//     F(q) dV/dq = -2 M.
//
// For mass elements at x + R rho_i with inertial forces f_i, M = sum rho_i x
// (R^T f_i): the physical torque about the centre of mass, in body axes.
#pragma once

#include <lgvi/error.hpp>
#include <lgvi/rigid_body.hpp>
#include <lgvi/s3.hpp>

#include <cmath>
#include <concepts>
#include <functional>
#include <vector>

namespace lgvi {

/// What a potential returns at (x, q).
struct PotentialEvaluation {
  double energy = 0.0;                                 ///< V(x, q)
  Vector3<double> force = Vector3<double>::Zero();   ///< -dV/dx, inertial frame
  Vector3<double> torque = Vector3<double>::Zero();  ///< M, body frame; F(q) dV/dq = -2 M

  bool all_finite() const { return std::isfinite(energy) && force.allFinite() && torque.allFinite(); }
};

/// The contract of a potential: evaluate(x, q) gives energy, force, torque.
template <class P>
concept Potential = requires(const P& p, const Vector3<double>& x, const S3d& q) {
  { p.evaluate(x, q) } -> std::same_as<PotentialEvaluation>;
};

/// The free body: V = 0.
struct NoPotential {
  PotentialEvaluation evaluate(const Vector3<double>&, const S3d&) const { return {}; }
};

/// Uniform gravity V = -m g . x with g the acceleration (e.g. (0, 0, -9.81)).
/// The resultant acts at the centre of mass, so the torque about it is zero.
class UniformGravity {
 public:
  UniformGravity(const RigidBody& body, const Vector3<double>& g) : mass_(body.mass()), g_(g) {}
  PotentialEvaluation evaluate(const Vector3<double>& x, const S3d&) const {
    PotentialEvaluation e;
    e.energy = -mass_ * g_.dot(x);
    e.force = mass_ * g_;
    return e;
  }

 private:
  double mass_;
  Vector3<double> g_;
};

/// Central gravity of a point source of strength mu at the origin, summed
/// over the body's balls:  V = -mu sum_i m_i / |x + pi(q) rho_i|.
/// (A uniform ball attracts as a point mass, so this is exact for balls
/// outside the source.) A body with no balls is a point mass m at x.
class CentralGravity {
 public:
  CentralGravity(const RigidBody& body, double mu) : mu_(mu) {
    if (body.balls().empty()) {
      rho_.push_back(Vector3<double>::Zero());
      mass_.push_back(body.mass());
    } else {
      for (const Ball& b : body.balls()) {
        rho_.push_back(b.position);
        mass_.push_back(b.mass);
      }
    }
  }

  PotentialEvaluation evaluate(const Vector3<double>& x, const S3d& q) const {
    const Matrix3<double> r = q.matrix();
    PotentialEvaluation e;
    Vector3<double> torque_inertial = Vector3<double>::Zero();
    for (std::size_t i = 0; i < rho_.size(); ++i) {
      const Vector3<double> arm = r * rho_[i];  // pi(q) rho_i
      const Vector3<double> pos = x + arm;
      const double d2 = pos.squaredNorm();
      const double inv_d = 1.0 / std::sqrt(d2);
      const double mu_m_inv_d = mu_ * mass_[i] * inv_d;
      e.energy -= mu_m_inv_d;
      const Vector3<double> f = (-mu_m_inv_d * inv_d * inv_d) * pos;  // -dV_i/dx
      e.force += f;
      torque_inertial += arm.cross(f);
    }
    e.torque = r.transpose() * torque_inertial;
    return e;
  }

 private:
  double mu_;
  std::vector<Vector3<double>> rho_;
  std::vector<double> mass_;
};

/// A potential given by a user's C++ callable (x, q) -> PotentialEvaluation.
/// Its derivatives can be verified with `check_potential_derivatives`.
class CallablePotential {
 public:
  using Function = std::function<PotentialEvaluation(const Vector3<double>&, const S3d&)>;
  explicit CallablePotential(Function f) : f_(std::move(f)) {}
  PotentialEvaluation evaluate(const Vector3<double>& x, const S3d& q) const { return f_(x, q); }

 private:
  Function f_;
};

/// The paper's rotational generalized force F(q) dV/dq from the torque M.
inline Vector3<double> seed_torque_term(const Vector3<double>& torque) { return -2.0 * torque; }

/// Largest discrepancies between a potential's force and torque and central
/// finite differences of its energy, each relative to max(1, |value|).
struct DerivativeCheck {
  double force_error = 0.0;
  double torque_error = 0.0;
  bool passed(double tolerance) const { return force_error <= tolerance && torque_error <= tolerance; }
};

/// Checks force = -dV/dx and torque = -dV/dtheta (theta the body-frame
/// rotation, q -> q exp(theta/2)) by central differences of the energy with
/// step h. With V smooth, the truncation error is O(h^2) and the round-off
/// O(eps |V| / h): h ~ eps^(1/3) |x| balances them at ~1e-10 relative.
template <Potential P>
DerivativeCheck check_potential_derivatives(const P& potential, const Vector3<double>& x, const S3d& q,
                                            double h = 0.0) {
  if (h <= 0.0) h = std::cbrt(std::numeric_limits<double>::epsilon()) * std::max(1.0, x.norm());
  const PotentialEvaluation e = potential.evaluate(x, q);
  Vector3<double> force_fd, torque_fd;
  for (int i = 0; i < 3; ++i) {
    Vector3<double> dx = Vector3<double>::Zero();
    dx(i) = h;
    force_fd(i) = -(potential.evaluate(x + dx, q).energy - potential.evaluate(x - dx, q).energy) / (2 * h);
    // delta R = R hat(delta theta) <=> delta q = q exp(delta theta / 2).
    const S3d qp = q * S3d::exp(dx / 2.0), qm = q * S3d::exp(-dx / 2.0);
    torque_fd(i) = -(potential.evaluate(x, qp).energy - potential.evaluate(x, qm).energy) / (2 * h);
  }
  DerivativeCheck c;
  c.force_error = (e.force - force_fd).norm() / std::max(1.0, e.force.norm());
  c.torque_error = (e.torque - torque_fd).norm() / std::max(1.0, e.torque.norm());
  return c;
}

}  // namespace lgvi
