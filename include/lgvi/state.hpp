// The state (x, q, p, w) on T*(R^3 x S^3) and its diagnostics.
//
// Paper symbols: x centre of mass (inertial), q attitude in S^3, p = m xdot
// linear momentum, w = 2 J Omega the left-trivialized angular momentum in
// the Lie algebra dual (the paper's Legendre transform xi -> 4 J xi with
// Omega = 2 xi). So the body angular momentum is J Omega = w / 2.
#pragma once

#include <lgvi/potential.hpp>
#include <lgvi/rigid_body.hpp>
#include <lgvi/s3.hpp>

namespace lgvi {

struct RigidBodyState {
  Vector3<double> x = Vector3<double>::Zero();
  S3d q;
  Vector3<double> p = Vector3<double>::Zero();
  Vector3<double> w = Vector3<double>::Zero();

  bool all_finite() const {
    return x.allFinite() && q.all_finite() && p.allFinite() && w.allFinite();
  }
};

/// The state in the rotation-matrix representation, (x, R, xdot, Omega).
struct RotationMatrixState {
  Vector3<double> x;
  Matrix3<double> R;
  Vector3<double> xdot;
  Vector3<double> omega;  ///< body angular velocity Omega
};

/// The paper's "Implementation of algorithm", steps 1-2: lift (x, R) to
/// (x, q) with pi(q) = R, and start from p = m xdot, w = 2 J Omega.
inline RigidBodyState lift(const RotationMatrixState& s, const RigidBody& body) {
  return {s.x, S3d::from_rotation_matrix(s.R), body.mass() * s.xdot, 2.0 * body.inertia() * s.omega};
}

/// The paper's projection to TSE(3): R = pi(q), xdot = p/m,
/// Omega = J^{-1} w / 2.
inline RotationMatrixState project(const RigidBodyState& s, const RigidBody& body) {
  return {s.x, s.q.matrix(), s.p / body.mass(), 0.5 * body.inertia_inverse() * s.w};
}

/// Rotational kinetic energy Omega^T J Omega / 2 = w^T J^{-1} w / 8 of a
/// body with momentum w (= pi^T J^{-1} pi / 2, body angular momentum pi = w / 2).
inline double rotational_kinetic_energy(const Vector3<double>& w, const RigidBody& body) {
  return w.dot(body.inertia_inverse() * w) / 8.0;
}

/// Kinetic energy |p|^2/(2m) + Omega^T J Omega / 2 = |p|^2/(2m) + w^T J^{-1} w / 8.
inline double kinetic_energy(const RigidBodyState& s, const RigidBody& body) {
  return s.p.squaredNorm() / (2.0 * body.mass()) + rotational_kinetic_energy(s.w, body);
}

/// Total energy, with V from an evaluation at the same state.
inline double total_energy(const RigidBodyState& s, const RigidBody& body, const PotentialEvaluation& e) {
  return kinetic_energy(s, body) + e.energy;
}

/// Total angular momentum about the origin, x cross p + pi(q) J Omega
/// = x cross p + pi(q) w / 2: the momentum map of the paper's S^3 action
/// (x, q) -> (pi(q1) x, q1 q), conserved by discrete Noether's theorem for
/// potentials invariant under it (none, central).
inline Vector3<double> angular_momentum(const RigidBodyState& s) {
  return s.x.cross(s.p) + s.q.act(0.5 * s.w);
}

}  // namespace lgvi
