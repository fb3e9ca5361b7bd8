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

/// A heavy top: the body turns about a fixed pivot in a uniform field g,
/// V = -m g . (pi(q) chi), chi the centre of mass seen from the pivot in body
/// axes. The pivot's reaction balances the weight, so the force is zero and
/// x, p stay as they are (put the pivot at x = 0, p = 0); the body torque is
/// M = chi x (pi(q)^T m g). The body's inertia must then be taken about the
/// pivot (parallel axes: J_pivot = J_cm + m (|chi|^2 I - chi chi^T)). Only the
/// angular momentum about g is conserved.
class HeavyTop {
 public:
  HeavyTop(const RigidBody& body, const Vector3<double>& g, const Vector3<double>& chi)
      : weight_(body.mass() * g), chi_(chi) {}
  PotentialEvaluation evaluate(const Vector3<double>&, const S3d& q) const {
    PotentialEvaluation e;
    const Vector3<double> weight_body = q.inverse().act(weight_);
    e.energy = -weight_body.dot(chi_);
    e.torque = chi_.cross(weight_body);
    return e;
  }

 private:
  Vector3<double> weight_, chi_;
};

/// Central gravity of a point source of strength mu at the origin, summed
/// over the body's balls:  V = -mu sum_i m_i / |x + pi(q) rho_i|.
/// (A uniform ball attracts as a point mass, so this is exact for balls
/// outside the source.)
///
/// A body given by mass and inertia (no balls) feels the second-order
/// (MacCullagh) potential of its mass distribution, the same model as
/// MutualGravityInertia between bodies:
///   V = -mu m / r - (mu / 2 r^3) (tr I - 3 rhat^T I rhat),  I = R J R^T,
/// r = x, R = pi(q), J the standard inertia (body axes). With u = R^T rhat
/// (rhat in body axes) the force and the body torque are
///   -dV/dx = -mu m x / r^3 - (3 mu / 2 r^4) [(tr J - 5 u^T J u) rhat + 2 R J u],
///   M = (3 mu / r^3) u x J u  (the gravity-gradient torque),
/// the torque from delta(u^T J u) = -2 theta . (u x J u) under R -> R exp(hat theta)
/// (checked against finite differences of V in tests/test_gravity_gradient.cpp).
/// The neglected terms are those of the third and higher moments: relative
/// to the gradient term O(size / r), and O((size / r)^2) for a body whose mass
/// is symmetric about its centre; the model holds for r much larger than the
/// body (a satellite, not a close pass). `Model::PointMass` drops the gradient
/// term: a mass + inertia body is then a point mass m at x (no torque);
/// bodies of balls are the same in both.
///
/// Close encounters: a ball (or point mass) whose centre reaches the source
/// makes the evaluation throw StepFailure naming the ball and the distance,
/// so the run stops at that step instead of producing non-finite numbers.
/// With `stop_at_contact`, it stops already when a ball's centre comes within
/// its radius of the source, where the point-mass formula no longer holds for
/// a solid ball; by default (as in the paper) the balls interact as point
/// masses and their radii only enter the inertia.
///
/// An oblate source (J2): with `j2` != 0, a reference radius R and the unit
/// pole k, each ball feels the field's second zonal harmonic,
///   V_i = -mu m_i / r [1 - J2 (R/r)^2 P2(k . r/|r|)],  P2(s) = (3 s^2 - 1)/2,
/// r = x + pi(q) rho_i, with the force from the exact gradient
///   -dV_i/dr = -mu m_i r / |r|^3 - (3/2) J2 mu m_i R^2 / |r|^5 [(1 - 5 z^2/|r|^2) r + 2 z k],  z = k . r
/// (Vallado, Fundamentals of Astrodynamics and Applications, 4th ed., 8.6.1;
/// checked against finite differences of V in tests/test_j2.cpp). The field is
/// symmetric about the pole, so the angular momentum about the pole, k . L,
/// is conserved by the discrete flow (discrete Noether); the other components
/// of L change. On a body given by mass and inertia the J2 term acts on the
/// centre of mass (its torque on the body, smaller than the central term's
/// gradient torque by J2 (R / r)^2, is not modelled).
class CentralGravity {
 public:
  /// How the field acts on a body given by mass and inertia. A body of balls
  /// is the same in both: each ball a point mass (a uniform ball attracts as one).
  enum class Model {
    Extended,  ///< its second-order (MacCullagh) potential, with the gravity-gradient torque
    PointMass  ///< a point mass m at its centre of mass (no torque)
  };
  /// A point source (J2 = 0).
  CentralGravity(const RigidBody& body, double mu, bool stop_at_contact = false, Model model = Model::Extended)
      : CentralGravity(body, mu, stop_at_contact, 0.0, 0.0, Vector3<double>::UnitZ(), model) {}
  /// An oblate source: J2, reference radius R > 0 and pole k (normalized here;
  /// InvalidInput if it is zero or R is not > 0 while J2 != 0).
  CentralGravity(const RigidBody& body, double mu, bool stop_at_contact, double j2, double reference_radius,
                 const Vector3<double>& pole, Model model = Model::Extended)
      : mu_(mu), j2_(j2), radius2_ref_(reference_radius * reference_radius) {
    if (j2_ != 0.0) {
      if (!(reference_radius > 0.0 && std::isfinite(reference_radius)))
        throw InvalidInput("potential.reference_radius: must be > 0 (the radius J2 refers to)");
      if (!(pole.norm() > 0.0 && pole.allFinite())) throw InvalidInput("potential.pole: must be a non-zero vector");
      pole_ = pole.normalized();
    }
    if (body.balls().empty()) {
      whole_body_ = true;
      rho_.emplace_back(Vector3<double>::Zero());
      mass_.push_back(body.mass());
      // With stop_at_contact a body of known extent (a sphere, a bounding
      // sphere, an ellipsoid) stops when the source lies inside it; a body given
      // by mass + inertia alone, when its centre of mass reaches the source.
      radius2_.push_back(stop_at_contact && body.extent() == Extent::Sphere ? body.semi_axes().x() * body.semi_axes().x()
                                                                            : 0.0);
      if (stop_at_contact && body.extent() == Extent::Ellipsoid)
        inverse_axes2_ = body.semi_axes().cwiseProduct(body.semi_axes()).cwiseInverse();
      if (model == Model::Extended) {
        gradient_ = true;
        inertia_ = body.inertia();
        trace_inertia_ = inertia_.trace();
      }
    } else {
      for (const Ball& b : body.balls()) {
        rho_.push_back(b.position);
        mass_.push_back(b.mass);
        radius2_.push_back(stop_at_contact ? b.radius * b.radius : 0.0);
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
      if (!(d2 > radius2_[i])) close_encounter(i, d2);
      // An ellipsoid holds the source when (R^T (-x))_k^2 / a_k^2 sums to <= 1.
      if (inverse_axes2_.x() > 0.0 && !((r.transpose() * pos).cwiseAbs2().dot(inverse_axes2_) > 1.0))
        close_encounter(i, d2);
      const double inv_d = 1.0 / std::sqrt(d2);
      const double mu_m_inv_d = mu_ * mass_[i] * inv_d;
      e.energy -= mu_m_inv_d;
      Vector3<double> f = (-mu_m_inv_d * inv_d * inv_d) * pos;  // -dV_i/dx
      if (j2_ != 0.0) {
        // V_J2 = mu m J2 R^2 P2(z/r) / r^3; its force, above.
        const double z = pole_.dot(pos), inv_d2 = inv_d * inv_d, zr2 = z * z * inv_d2;
        const double c = j2_ * radius2_ref_ * mu_m_inv_d * inv_d2;  // mu m J2 R^2 / r^3
        e.energy += c * 0.5 * (3.0 * zr2 - 1.0);
        f -= (1.5 * c * inv_d2) * ((1.0 - 5.0 * zr2) * pos + (2.0 * z) * pole_);
      }
      e.force += f;
      torque_inertial += arm.cross(f);
    }
    e.torque = r.transpose() * torque_inertial;
    if (gradient_) add_gradient_term(x, r, e);
    return e;
  }

  /// Whether the body feels the gravity-gradient (second-order) term.
  bool has_gradient_term() const { return gradient_; }

 private:
  /// The second-order term of a mass + inertia body at x with R = pi(q) (the
  /// class comment's formulas), added to e; x != 0 was checked by evaluate.
  void add_gradient_term(const Vector3<double>& x, const Matrix3<double>& r, PotentialEvaluation& e) const {
    const double inv_d = 1.0 / x.norm();
    const Vector3<double> rhat = inv_d * x;
    const Vector3<double> u = r.transpose() * rhat;  // rhat in body axes
    const Vector3<double> ju = inertia_ * u;
    const double uju = u.dot(ju);
    const double c = mu_ * inv_d * inv_d * inv_d;  // mu / r^3
    e.energy -= 0.5 * c * (trace_inertia_ - 3.0 * uju);
    e.force -= (1.5 * c * inv_d) * ((trace_inertia_ - 5.0 * uju) * rhat + 2.0 * (r * ju));
    e.torque += (3.0 * c) * u.cross(ju);
  }

  [[noreturn]] void close_encounter(std::size_t i, double d2) const {
    if (std::isnan(d2)) throw StepFailure("the state became non-finite", "try a smaller step");
    const bool surface = radius2_[i] > 0.0 || inverse_axes2_.x() > 0.0;
    throw StepFailure((whole_body_ ? (surface     ? std::string("the body's surface")
                                      : gradient_ ? std::string("the body's centre of mass")
                                                  : std::string("the point-mass body"))
                       : rho_.size() == 1 && radius2_[0] == 0.0 ? std::string("the point-mass body")
                                                                : "ball " + std::to_string(i)) +
                          " reached the centre of the central field (distance " + std::to_string(std::sqrt(d2)) +
                          (radius2_[i] > 0.0 ? " <= its radius " + std::to_string(std::sqrt(radius2_[i])) : "") +
                          "): a collision with the attracting point, where the potential is not defined",
                      "the motion itself ends here; if the approach was not expected, a smaller step resolves "
                      "close passes better");
  }

  double mu_;
  double j2_ = 0.0, radius2_ref_ = 0.0;
  Vector3<double> pole_ = Vector3<double>::UnitZ();
  std::vector<Vector3<double>> rho_;
  std::vector<double> mass_;
  std::vector<double> radius2_;
  Vector3<double> inverse_axes2_ = Vector3<double>::Zero();  ///< an ellipsoid's 1 / a_k^2 (stop_at_contact)
  bool whole_body_ = false;  ///< a body without balls (mass + inertia, a shape): one site at its centre
  bool gradient_ = false;    ///< such a body in the Extended model
  Matrix3<double> inertia_ = Matrix3<double>::Zero();
  double trace_inertia_ = 0.0;
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

/// Discrepancies between a potential's force and torque and finite
/// differences of its energy, each relative to the larger of the two values
/// compared (0 when both are exactly 0).
struct DerivativeCheck {
  double force_error = 0.0;
  double torque_error = 0.0;
  /// The largest |difference| itself (not relative): for a sum of many terms
  /// whose total nearly cancels, judged against the terms' size by the caller.
  double force_abs_error = 0.0;
  double torque_abs_error = 0.0;
  bool passed(double tolerance) const { return force_error <= tolerance && torque_error <= tolerance; }
};

/// Checks force = -dV/dx and torque = -dV/dtheta (theta the body-frame
/// rotation angle: q -> q exp(theta/2), i.e. R -> R expm(hat(theta))) by
/// fourth-order central differences of the energy,
///   f'(0) ~ (8 (f(h) - f(-h)) - (f(2h) - f(-2h))) / (12 h),
/// with h = eps^(1/5) (times max(1, |x|) for positions): the truncation
/// O(h^4) and the round-off O(eps |V| / h) are then both ~1e-13 |V|. A
/// derivative much smaller than |V| (a tidal torque far from the centre) is
/// checked relative to itself, so its achievable accuracy is eps |V| / (h |M|).
template <Potential P>
DerivativeCheck check_potential_derivatives(const P& potential, const Vector3<double>& x, const S3d& q) {
  const double h0 = std::pow(std::numeric_limits<double>::epsilon(), 0.2);
  const PotentialEvaluation e = potential.evaluate(x, q);
  Vector3<double> force_fd, torque_fd;
  auto diff = [](auto&& f, double h) { return (8.0 * (f(h) - f(-h)) - (f(2 * h) - f(-2 * h))) / (12.0 * h); };
  for (int i = 0; i < 3; ++i) {
    const Vector3<double> unit = Vector3<double>::Unit(i);
    force_fd(i) = -diff([&](double t) { return potential.evaluate(x + t * unit, q).energy; }, h0 * std::max(1.0, x.norm()));
    torque_fd(i) = -diff([&](double t) { return potential.evaluate(x, q * S3d::exp((t / 2) * unit)).energy; }, h0);
  }
  auto relative = [](const Vector3<double>& a, const Vector3<double>& b) {
    const double scale = std::max(a.norm(), b.norm());
    return scale > 0.0 ? (a - b).norm() / scale : 0.0;
  };
  return {relative(e.force, force_fd), relative(e.torque, torque_fd)};
}

}  // namespace lgvi
