// Newtonian gravity between the bodies of a system, in two models.
//
//  * Balls (the mascon model of asteroid and spacecraft dynamics): every pair
//    of sites of different bodies attracts as point masses,
//      V = -G sum_{a<b} sum_{i in a, j in b} m_i m_j / |X_j - X_i|,
//    X_i = x_a + R_a rho_i. (A uniform ball attracts as a point mass, so this
//    is exact for non-overlapping balls.) Direct summation: the cost is
//    O(S^2) for S sites in all, each pair evaluated from both sides so that
//    each body's sum runs on one thread in a fixed order (parallel.hpp).
//
//  * Inertia: each body as its mass and inertia tensor, the mutual potential
//    truncated at second order (MacCullagh), as in full two-body problem
//    codes (Lee, Leok & McClamroch 2007; GUBAS at order 2):
//      V_ab = -G m_a m_b / r - (G / 2 r^3) (tr S - 3 rhat^T S rhat),
//      S = m_b I_a + m_a I_b,  I_a = R_a J_a R_a^T,  r = x_b - x_a.
//    Derivatives (r = |r|, with rS = r^T S r):
//      dV/dr = G m_a m_b r / r^3 + (3G/2) tr S r / r^5 + 3G S r / r^5 - (15G/2) rS r / r^7,
//      F_a = dV/dr, F_b = -dV/dr,
//    and, with u = R_a^T rhat (the direction of b in a's body axes), the
//    body torque on a from delta I_a = R_a (hat(theta) J_a - J_a hat(theta)) R_a^T:
//      M_a = (3 G m_b / r^3) u x (J_a u)      (the gravity-gradient torque).
//
// Both are invariant under a common translation and rotation, so the total
// linear and angular momentum are conserved by the LGVI (tests/test_nbody.cpp).
// The pair terms are computed so that the force of b on a is exactly minus
// that of a on b (IEEE products and sums are commutative; negating r negates
// every odd term exactly): Newton's third law holds bit for bit per pair.
#pragma once

#include <lgvi/interaction.hpp>

#include <cmath>
#include <memory>
#include <vector>

namespace lgvi {

namespace detail {
/// Gravity is long-range: in a periodic box its sum over images does not
/// converge absolutely (it needs Ewald summation, which lgvi does not have).
inline void require_open_space(const System& sys) {
  if (sys.box().any_periodic())
    throw InvalidInput("box.periodic: mutual gravity is long-range and has no minimum image (a periodic box would "
                       "need Ewald summation); use an open box (periodic = [false, false, false]) or a short-range "
                       "pair interaction (lennard-jones, wca)");
}
}  // namespace detail

/// Mutual gravity between the balls (sites) of different bodies. The model:
/// the bodies, their sites and G (shared by copies); the workspace: the
/// sites' places and the bodies' energies.
class MutualGravityBalls {
 public:
  MutualGravityBalls(const System& sys, double G, Parallelism par = {}) : par_(par) {
    if (!(std::isfinite(G) && G > 0.0)) throw InvalidInput("interaction.G: must be a finite number > 0");
    detail::require_open_space(sys);
    auto model = std::make_shared<Model>(Model{sys, InteractionSites(sys), G, {}});
    model->mass.resize(model->sites.size());
    for (std::size_t i = 0; i < model->mass.size(); ++i) model->mass[i] = model->sites.mass(i);
    model_ = std::move(model);
  }

  void add(const SystemState& s, SystemEvaluation& e) {
    const std::size_t n = s.size();
    const Model& m = *model_;
    std::vector<Vector3<double>>& position = work_.position;
    std::vector<Vector3<double>>& arm = work_.arm;
    std::vector<double>& body_energy = work_.energy;
    m.sites.place(s, par_, position, arm);
    body_energy.assign(n, 0.0);
    parallel_for(n, par_, [&](std::size_t a) {
      SiteWrench wrench;  // the pairs' forces at site i, in order of j
      double energy = 0.0;
      for (std::size_t i = m.sites.begin(a); i < m.sites.end(a); ++i) {
        const Vector3<double>& xi = position[i];
        const double mi = m.mass[i];
        for (std::size_t b = 0; b < n; ++b) {
          if (b == a) continue;
          for (std::size_t j = m.sites.begin(b); j < m.sites.end(b); ++j) {
            const Vector3<double> d = position[j] - xi;
            const double r2 = d.squaredNorm();
            const double inv_r = 1.0 / std::sqrt(r2);
            const double gmm_inv_r = m.G * (mi * m.mass[j]) * inv_r;
            if (!std::isfinite(gmm_inv_r)) detail::close_approach(m.sys, m.sites, i, j, std::sqrt(r2));
            wrench.add(arm[i], (gmm_inv_r * inv_r * inv_r) * d);  // towards site j
            if (b > a) energy -= gmm_inv_r;
          }
        }
      }
      wrench.add_to(s, a, e);
      body_energy[a] = energy;
    });
    for (std::size_t a = 0; a < n; ++a) e.energy += body_energy[a];
  }

  double G() const { return model_->G; }
  const InteractionSites& sites() const { return model_->sites; }

 private:
  struct Model {
    System sys;
    InteractionSites sites;
    double G;
    std::vector<double> mass;  ///< per site (the all-pairs loop reads it per pair; sites keeps it per kind)
  };
  struct Workspace {
    std::vector<Vector3<double>> position, arm;
    std::vector<double> energy;
  };
  std::shared_ptr<const Model> model_;
  Parallelism par_;
  Workspace work_;
};

/// Mutual gravity of bodies as masses with inertia tensors, to second order.
/// The model: the bodies and G (shared by copies); the workspace: the
/// inertia tensors in inertial axes and the bodies' energies.
class MutualGravityInertia {
 public:
  MutualGravityInertia(const System& sys, double G, Parallelism par = {}) : par_(par) {
    if (!(std::isfinite(G) && G > 0.0)) throw InvalidInput("interaction.G: must be a finite number > 0");
    detail::require_open_space(sys);
    model_ = std::make_shared<const Model>(Model{sys, G});
  }

  void add(const SystemState& s, SystemEvaluation& e) {
    const std::size_t n = s.size();
    const System& sys = model_->sys;
    const double G = model_->G;
    std::vector<Matrix3<double>>& inertial = work_.inertial;
    std::vector<double>& body_energy = work_.energy;
    inertial.resize(n);
    parallel_for(n, par_, [&](std::size_t a) {
      const Matrix3<double> r = s.q[a].matrix();
      inertial[a] = r * sys.body(a).inertia() * r.transpose();
    });
    body_energy.assign(n, 0.0);
    parallel_for(n, par_, [&](std::size_t a) {
      const double ma = sys.body(a).mass();
      const Matrix3<double>& ja = sys.body(a).inertia();
      Vector3<double> force = Vector3<double>::Zero(), torque = Vector3<double>::Zero();
      double energy = 0.0;
      for (std::size_t b = 0; b < n; ++b) {
        if (b == a) continue;
        const double mb = sys.body(b).mass();
        const Vector3<double> r = s.x[b] - s.x[a];
        const double r2 = r.squaredNorm();
        const double inv_r = 1.0 / std::sqrt(r2);
        const double inv_r2 = inv_r * inv_r;
        const double inv_r3 = inv_r2 * inv_r;
        const double inv_r5 = inv_r3 * inv_r2;
        // S symmetric in (a, b): the sum of the same two products either way.
        const Matrix3<double> S = a < b ? Matrix3<double>(mb * inertial[a] + ma * inertial[b])
                                        : Matrix3<double>(ma * inertial[b] + mb * inertial[a]);
        const Vector3<double> sr = S * r;
        const double rsr = r.dot(sr);
        const double trace = S.trace();
        const double gmm = G * (ma * mb);
        if (!std::isfinite(gmm * inv_r3)) close_approach(a, b, std::sqrt(r2));
        // dV/dr, the force on a (towards b for the monopole).
        force += (gmm * inv_r3 + 1.5 * G * trace * inv_r5 - 7.5 * G * rsr * inv_r5 * inv_r2) * r +
                 (3.0 * G * inv_r5) * sr;
        const Vector3<double> u = s.q[a].inverse().act(r * inv_r);
        torque += (3.0 * G * mb * inv_r3) * u.cross(ja * u);
        if (b > a) energy += -gmm * inv_r - 0.5 * G * inv_r3 * (trace - 3.0 * rsr * inv_r2);
      }
      e.force[a] += force;
      e.torque[a] += torque;
      body_energy[a] = energy;
    });
    for (std::size_t a = 0; a < n; ++a) e.energy += body_energy[a];
  }

  double G() const { return model_->G; }

 private:
  [[noreturn]] void close_approach(std::size_t a, std::size_t b, double d) const {
    const System& sys = model_->sys;
    throw StepFailure("the mutual gravity between body " + std::to_string(a) + " (\"" + sys.name(a) +
                          "\") and body " + std::to_string(b) + " (\"" + sys.name(b) +
                          "\") is not finite (distance " + std::to_string(d) + "): a collision",
                      "the mass-and-inertia model holds only for bodies well apart; a smaller step resolves close "
                      "approaches better");
  }

  struct Model {
    System sys;
    double G;
  };
  struct Workspace {
    std::vector<Matrix3<double>> inertial;
    std::vector<double> energy;
  };
  std::shared_ptr<const Model> model_;
  Parallelism par_;
  Workspace work_;
};

}  // namespace lgvi
