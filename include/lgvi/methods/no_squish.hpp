// NO_SQUISH: the symplectic quaternion splitting of Miller, Eleftheriou,
// Pattnaik, Ndirango, Newns & Martyna, "Symplectic quaternion scheme for
// biophysical molecular dynamics", J. Chem. Phys. 116, 8649 (2002), as in
// LAMMPS fix rigid/nve (MathExtra::no_squish_rotate) and HOOMD-blue's
// TwoStepNVE.
//
// Variables. The paper's quaternion is scalar first, like ours, and its
// S(q) and P_k are Hamilton-product matrices in that order:
//   S(q) r = q r,        P_k r = r (0, e_k)      (k = 1, 2, 3),
//   P_1 r = (-r1, r0, r3, -r2), P_2 r = (-r2, -r3, r0, r1), P_3 r = (-r3, r2, -r1, r0).
// Its conjugate momentum p = 2 S(q) (0, J Omega) is, with our w = 2 J Omega,
//   P = q (0, w)   and back   w = Im(q^* P) = Im(S(q)^T P).
// (No frame translation is needed: in our convention too the attitude is
// body -> inertial, Omega the body angular velocity.) Then
// P^T P_k q = <q (0, w), q (0, e_k)> = w_k, and the free-rotation
// Hamiltonian is sum_k (P^T P_k q)^2 / (8 J_k) = sum_k Pi_k^2 / (2 J_k).
//
// One step:
//   p += (h/2) F,   P += (h/2) 2 S(q) (0, M) = h q (0, M)       (half kicks)
//   free rotation: rot_3(h/2) rot_2(h/2) rot_1(h) rot_2(h/2) rot_3(h/2), with
//     rot_k(t):  zeta = P^T P_k q / (4 J_k)    (= Omega_k / 2, constant along it)
//                q <- cos(zeta t) q + sin(zeta t) P_k q
//                P <- cos(zeta t) P + sin(zeta t) P_k P
//   x += h p / m                                                (drift)
//   p += (h/2) F,   P += h q (0, M)   at the new (x, q)          (half kicks)
// rot_k is the exact flow of (P^T P_k q)^2/(8 J_k): q <- q exp(e_k zeta t),
// the body rotation by Omega_k t about e_k, with w rotated back. It is
// orthogonal on (q, P), so |q| = 1 and q^T P = 0 hold up to rounding without
// normalization. Palindromic composition of exact flows: symplectic,
// time-reversible, second order. (The same sub-flows as the DLM splitting in
// splitting_dlm.hpp, composed in the order 3, 2, 1, 2, 3 and carried on
// (q, P) in R^8 instead of (q, Pi).)
//
// State: P is rebuilt from (q, w) at the start of each step and w read back
// at the end, so (x, q, p, w) is the whole state (LAMMPS keeps conjqm
// between steps instead; the two agree in exact arithmetic, and here the
// rounding component q^T P is dropped once per step).
//
// Principal axes: required as for the DLM splitting (J diagonal up to
// 8 eps max J_kk, else InvalidInput).
//
// Cost: 1 potential evaluation per step (the closing kick's F and M serve
// the next step; initialize() adds one).
#pragma once

#include <lgvi/methods/method_traits.hpp>
#include <lgvi/methods/explicit_stepper.hpp>

#include <cmath>
#include <vector>

namespace lgvi {

template <SystemPotential I>
class NoSquishIntegrator : public detail::ExplicitStepperBase<I> {
 public:
  static constexpr MethodTraits traits{"no-squish", "the NO_SQUISH splitting of Miller et al. (2002)", 2,
                                      /*symmetric=*/true, /*two_step=*/false, /*implicit=*/false,
                                      /*accepts_forcing=*/false, /*needs_principal_axes=*/true,
                                      /*free_body_only=*/false, /*linear_bodies=*/false};

  NoSquishIntegrator(System system, I potential, SolverOptions = {}, Parallelism par = {})
      : detail::ExplicitStepperBase<I>(std::move(system), std::move(potential), par, "the no-squish integrator") {
    for (const RigidBody& b : system_bodies(this->system_)) moments_.push_back(detail::require_principal_axes(b, "no-squish"));
    mom_.resize(this->system_.size());
  }

  void step(SystemState& s, double /*t*/, double h) {
    const System& sys = this->system_;
    detail::for_each_body(sys, this->par_, [&](std::size_t a) {
      Vector4<double> q = s.q[a].scalar_first();
      Vector4<double> mom = S(q) * pure(s.w[a]);  // P = 2 S(q) (0, J Omega)
      s.p[a] += (0.5 * h) * this->eval_.force[a];
      mom += h * (S(q) * pure(this->eval_.torque[a]));
      rotate(a, 3, 0.5 * h, q, mom);
      rotate(a, 2, 0.5 * h, q, mom);
      rotate(a, 1, h, q, mom);
      rotate(a, 2, 0.5 * h, q, mom);
      rotate(a, 3, 0.5 * h, q, mom);
      s.q[a] = S3d(q(0), q(1), q(2), q(3));
      s.x[a] += (h / sys.body(a).mass()) * s.p[a];
      mom_[a] = mom;
    });
    this->evaluate_at(s);
    detail::for_each_body(sys, this->par_, [&](std::size_t a) {
      const Vector4<double> q = s.q[a].scalar_first();
      s.p[a] += (0.5 * h) * this->eval_.force[a];
      mom_[a] += h * (S(q) * pure(this->eval_.torque[a]));
      // (0, w) = S(q)^{-1} P = S(q)^T P / |q|^2. The rotations keep |q| = 1 only
      // to rounding; dividing by the |q|^2 it has keeps w -> P -> w the identity,
      // where S(q)^T alone would scale w by |q|^2 every step, a systematic drift
      // (|q| - 1 persists between steps) that would break the reversibility test
      // (7e-11 instead of 5e-14 after 1000 steps forward and back).
      s.w[a] = (S(q).transpose() * mom_[a]).template tail<3>() / q.squaredNorm();
    });
    this->finish_step(s);
  }

 private:
  static Vector4<double> pure(const Vector3<double>& v) { return Vector4<double>(0.0, v.x(), v.y(), v.z()); }
  /// The paper's S(q): S(q) r = q r (Hamilton product, scalar first).
  static Eigen::Matrix4d S(const Vector4<double>& q) {
    Eigen::Matrix4d m;
    m << q(0), -q(1), -q(2), -q(3),  //
        q(1), q(0), -q(3), q(2),     //
        q(2), q(3), q(0), -q(1),     //
        q(3), -q(2), q(1), q(0);
    return m;
  }
  /// The paper's permutations P_k r = r (0, e_k).
  static Vector4<double> permute(int k, const Vector4<double>& r) {
    switch (k) {
      case 1: return Vector4<double>(-r(1), r(0), r(3), -r(2));
      case 2: return Vector4<double>(-r(2), -r(3), r(0), r(1));
      default: return Vector4<double>(-r(3), r(2), -r(1), r(0));
    }
  }
  /// The exact flow of (P^T P_k q)^2 / (8 J_k) for time t.
  void rotate(std::size_t a, int k, double t, Vector4<double>& q, Vector4<double>& mom) const {
    const Vector4<double> pq = permute(k, q);
    const double zeta = mom.dot(pq) / (4.0 * moments_[a](k - 1));
    const double c = std::cos(zeta * t), s = std::sin(zeta * t);
    const Vector4<double> pp = permute(k, mom);
    q = c * q + s * pq;
    mom = c * mom + s * pp;
  }

  std::vector<Vector3<double>> moments_;
  std::vector<Vector4<double>> mom_;
};

}  // namespace lgvi
