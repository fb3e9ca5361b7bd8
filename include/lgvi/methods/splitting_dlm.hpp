// The symplectic splitting of Dullweber, Leimkuhler & McLachlan, "Symplectic
// splitting methods for rigid body molecular dynamics", J. Chem. Phys. 107,
// 5840 (1997), on the quaternion attitude.
//
// H = |p|^2/(2m) + sum_k Pi_k^2/(2 J_k) + V(x, q) is split into the kick V,
// the drift |p|^2/(2m) and the free rotation, itself split into the three
// exactly solvable H_k = Pi_k^2/(2 J_k) (Pi = w/2 body angular momentum in
// principal axes). One step (Strang / velocity Verlet in the outer split):
//   p  += (h/2) F(x, q),   Pi += (h/2) M(x, q)                (kick)
//   R_1(h/2) R_2(h/2) R_3(h) R_2(h/2) R_1(h/2)                (free rotation)
//   x  += h p / m                                             (drift)
//   p  += (h/2) F(x, q),   Pi += (h/2) M(x, q)                (kick)
// R_k(t) is the exact flow of H_k for time t: with theta = t Pi_k / J_k
// (Pi_k is constant along it),
//   Pi <- rot(e_k, -theta) Pi   (Pidot = Pi x Omega_k e_k: the body momentum
//                                turns backwards about e_k),
//   q  <- q exp(e_k theta / 2)  (the body turns by theta about its axis e_k;
//                                S3d::exp's convention).
// Each R_k is an exact rotation, so |Pi| and the spatial angular momentum
// pi(q) Pi are invariant under it, and |q| stays 1 up to rounding (no
// normalization anywhere). Every sub-flow is exact and the composition is
// palindromic: the method is symplectic, time-reversible, second order.
// The kicks change x cross p + pi(q) Pi by (h/2)(x x F + pi(q) M), zero for a
// potential invariant under rotations about the origin (central gravity), so
// the total angular momentum is then conserved to rounding as well.
//
// Principal axes: the body frame must be principal (J diagonal). Off-
// diagonal entries up to 8 eps max_k J_kk (the rounding of a computed
// inertia) are treated as zero; larger ones throw InvalidInput. Diagonalize
// the body first (rotate its balls into principal axes).
//
// Cost: 1 potential evaluation per step (the closing kick's F and M serve
// the next step's opening kick; initialize() adds one).
#pragma once

#include <lgvi/methods/method_traits.hpp>
#include <lgvi/methods/explicit_stepper.hpp>

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>
#include <vector>

namespace lgvi {

template <SystemPotential I>
class SplittingDlmIntegrator : public detail::ExplicitStepperBase<I> {
 public:
  static constexpr MethodTraits traits{"splitting-dlm", "the splitting of Dullweber, Leimkuhler & McLachlan (1997)", 2,
                                      /*symmetric=*/true, /*two_step=*/false, /*implicit=*/false,
                                      /*accepts_forcing=*/false, /*needs_principal_axes=*/true,
                                      /*free_body_only=*/false, /*linear_bodies=*/false};

  SplittingDlmIntegrator(System system, I potential, SolverOptions = {}, Parallelism par = {})
      : detail::ExplicitStepperBase<I>(std::move(system), std::move(potential), par, "the splitting-dlm integrator") {
    for (const RigidBody& b : system_bodies(this->system_)) moments_.push_back(detail::require_principal_axes(b, "splitting-dlm"));
    pi_.resize(this->system_.size());
  }

  void step(SystemState& s, double /*t*/, double h) {
    const System& sys = this->system_;
    detail::for_each_body(sys, this->par_, [&](std::size_t a) {
      s.p[a] += (0.5 * h) * this->eval_.force[a];
      Vector3<double> pi = 0.5 * s.w[a] + (0.5 * h) * this->eval_.torque[a];
      S3d q = s.q[a];
      rotate(a, 0, 0.5 * h, pi, q);
      rotate(a, 1, 0.5 * h, pi, q);
      rotate(a, 2, h, pi, q);
      rotate(a, 1, 0.5 * h, pi, q);
      rotate(a, 0, 0.5 * h, pi, q);
      s.q[a] = q;
      pi_[a] = pi;
      s.x[a] += (h / sys.body(a).mass()) * s.p[a];
    });
    this->evaluate_at(s);
    detail::for_each_body(sys, this->par_, [&](std::size_t a) {
      s.p[a] += (0.5 * h) * this->eval_.force[a];
      s.w[a] = 2.0 * (pi_[a] + (0.5 * h) * this->eval_.torque[a]);
    });
    this->finish_step(s);
  }

 private:
  /// R_k(t): the exact flow of Pi_k^2/(2 J_k) for time t.
  void rotate(std::size_t a, int k, double t, Vector3<double>& pi, S3d& q) const {
    const double theta = t * pi(k) / moments_[a](k);
    const int i = (k + 1) % 3, j = (k + 2) % 3;
    const double c = std::cos(theta), s = std::sin(theta);
    const double pi_i = pi(i), pi_j = pi(j);
    pi(i) = c * pi_i + s * pi_j;
    pi(j) = -s * pi_i + c * pi_j;
    q = q * S3d::exp((0.5 * theta) * Vector3<double>::Unit(k));
  }

  std::vector<Vector3<double>> moments_, pi_;
};

}  // namespace lgvi
