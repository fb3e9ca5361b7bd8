// A rigid body: total mass m, standard inertia J about the centre of mass,
// optionally the uniform balls it is made of (used by potentials that
// integrate over the body, such as CentralGravity), and what is known of its
// extent (for contact detection, contact.hpp): its balls, a uniform sphere or
// ellipsoid, a bounding sphere, or nothing (a point at the centre of mass).
//
// The paper's kinetic energy T = m|xdot|^2/2 + Omega^T J Omega / 2 assumes the
// body frame's origin is the centre of mass (its eq. for T uses
// int rho dm = 0); `from_balls` moves the origin there.
//
// Linear and point bodies (LAMMPS's rigid bodies with a zero principal
// moment). Point masses on one line, such as CO2 or N2, have no inertia about
// that line: J = I (1 - n n^T) with axis n. The Lagrangian does not depend on
// the rotation about n, so the body has two rotational degrees of freedom, its
// angular momentum has no component along n (the primary constraint
// dL/dOmega_n = 0), and the rotation about n is fixed to none (as LAMMPS sets
// omega_n = 0). A single point mass has J = 0 and no rotation at all. A
// principal moment below 1e-7 of the largest is zero, LAMMPS's threshold
// (fix rigid/small's EPSILON), so that a molecule written with a few digits
// is linear; J is then stored as the exact I (1 - n n^T), I the mean of the
// two others, and inertia_inverse() is its pseudo-inverse (1 - n n^T) / I.
// Only methods that say so in their traits take such bodies (lgvi.hpp).
//
// Reaction wheels (wheels.hpp) make a body a gyrostat: J is then the inertia
// with the wheels locked, and the wheels' axial momenta are part of the state
// (SystemState::eta). with_wheels() adds them; bodies without are unchanged.
#pragma once

#include <lgvi/error.hpp>
#include <lgvi/s3.hpp>
#include <lgvi/wheels.hpp>

#include <Eigen/Eigenvalues>

#include <algorithm>
#include <cmath>
#include <memory>
#include <numbers>
#include <string>
#include <vector>

namespace lgvi {

/// A uniform ball: a point mass at `position` (body frame) with the inertia
/// 2/5 m r^2 I of a solid sphere about its own centre. As an interaction
/// site it has a `type` (1, 2, ...; LAMMPS's atom types), which picks a
/// typed pair potential's coefficients.
struct Ball {
  Vector3<double> position = Vector3<double>::Zero();
  double mass = 0.0;
  double radius = 0.0;
  int type = 1;
};

/// What is known of a body's extent, in body axes about its centre of mass.
enum class Extent {
  Point,      ///< given by mass and inertia alone: nothing is known, it is treated as its centre of mass
  Sphere,     ///< within the sphere of radius r (a uniform sphere, or a bounding sphere given with mass + inertia)
  Ellipsoid,  ///< the uniform solid ellipsoid of semi-axes (a, b, c) along the body axes
  Balls       ///< the union of its balls
};

/// The volume 4/3 pi a b c of the ellipsoid of semi-axes (a, b, c) (a
/// sphere: a = b = c = r).
inline double ellipsoid_volume(const Vector3<double>& semi_axes) {
  return 4.0 / 3.0 * std::numbers::pi * semi_axes.x() * semi_axes.y() * semi_axes.z();
}

class RigidBody {
 public:
  /// A body given by mass and standard inertia J (body frame, about the
  /// centre of mass). Throws InvalidInput unless m > 0 is finite and J is
  /// symmetric positive semi-definite with principal moments that satisfy
  /// the triangle inequality (J1 + J2 >= J3 for every ordering); a zero
  /// moment makes a linear body, J = 0 a point (the file comment).
  RigidBody(double mass, const Matrix3<double>& inertia) : mass_(mass), inertia_(inertia) { validate(); }

  /// Whether to require the triangle inequality of the principal moments.
  enum class TriangleInequality { Require, Waive };

  /// As above, optionally waiving the triangle inequality: textbook test
  /// problems use moments no mass distribution has (Hairer, Lubich &
  /// Wanner's free body (2, 1, 2/3)); the equations of motion do not need it.
  RigidBody(double mass, const Matrix3<double>& inertia, TriangleInequality triangle)
      : mass_(mass), inertia_(inertia), require_triangle_(triangle == TriangleInequality::Require) {
    validate();
  }

  /// A body made of uniform balls. m = sum m_i; positions are shifted so
  /// that the centre of mass is the body origin; J = sum m_i (|rho_i|^2 I -
  /// rho_i rho_i^T) + 2/5 m_i r_i^2 I.
  static RigidBody from_balls(std::vector<Ball> balls) {
    if (balls.empty()) throw InvalidInput("body: at least one ball is needed");
    double m = 0.0;
    Vector3<double> c = Vector3<double>::Zero();
    for (std::size_t i = 0; i < balls.size(); ++i) {
      const Ball& b = balls[i];
      const std::string name = "body.ball[" + std::to_string(i) + "]";
      if (!b.position.allFinite()) throw InvalidInput(name + ".position: must be finite");
      if (!(std::isfinite(b.mass) && b.mass > 0.0))
        throw InvalidInput(name + ".mass: must be a finite number > 0, got " + std::to_string(b.mass));
      if (!(std::isfinite(b.radius) && b.radius >= 0.0))
        throw InvalidInput(name + ".radius: must be a finite number >= 0, got " + std::to_string(b.radius));
      if (b.type < 1) throw InvalidInput(name + ".type: must be an integer >= 1, got " + std::to_string(b.type));
      m += b.mass;
      c += b.mass * b.position;
    }
    c /= m;
    Matrix3<double> j = Matrix3<double>::Zero();
    for (Ball& b : balls) {
      b.position -= c;
      const Vector3<double>& r = b.position;
      j += b.mass * (r.squaredNorm() * Matrix3<double>::Identity() - r * r.transpose());
      j.diagonal().array() += 0.4 * b.mass * b.radius * b.radius;
    }
    RigidBody body(m, j, balls);
    return body;
  }

  /// A uniform solid sphere of mass m and radius r: J = 2/5 m r^2 I.
  static RigidBody sphere(double mass, double radius) {
    require_length(radius, "body.radius");
    RigidBody body(mass, Matrix3<double>::Identity() * (0.4 * mass * radius * radius));
    body.require_three_moments("body.radius");
    body.extent_ = Extent::Sphere;
    body.semi_axes_ = Vector3<double>::Constant(radius);
    return body;
  }

  /// A uniform solid ellipsoid of mass m with semi-axes (a, b, c) along the
  /// body axes: J = m/5 diag(b^2 + c^2, a^2 + c^2, a^2 + b^2).
  static RigidBody ellipsoid(double mass, const Vector3<double>& semi_axes) {
    for (int i = 0; i < 3; ++i) require_length(semi_axes(i), "body.semi_axes");
    const Vector3<double> s2 = semi_axes.cwiseProduct(semi_axes);
    const Vector3<double> moments(s2.y() + s2.z(), s2.x() + s2.z(), s2.x() + s2.y());
    RigidBody body(mass, Matrix3<double>(((mass / 5.0) * moments).asDiagonal()));
    body.require_three_moments("body.semi_axes");
    body.extent_ = Extent::Ellipsoid;
    body.semi_axes_ = semi_axes;
    return body;
  }

  /// This body (given by mass and inertia) with a bounding sphere of radius
  /// r about its centre of mass: it lies within it, and contact detection
  /// treats it as that sphere (a conservative test).
  RigidBody bounded_by(double radius) const {
    if (extent_ != Extent::Point) throw InvalidInput("body.radius: only a body given by mass + inertia takes a radius");
    require_length(radius, "body.radius");
    // Any mass within a sphere of radius R about its centre of mass has
    // tr J = 2 sum m_i |rho_i|^2 <= 2 m R^2: a smaller radius cannot hold this
    // inertia, and contact detection with it would not be conservative.
    const double least = std::sqrt(inertia_.trace() / (2.0 * mass_));
    if (radius < least * (1.0 - 1e-12))
      throw InvalidInput("body.radius: " + std::to_string(radius) + " cannot hold a body of this mass and inertia "
                         "(any mass within radius R has tr J <= 2 m R^2); give at least sqrt(tr J / 2m) = " +
                         std::to_string(least));
    RigidBody body = *this;
    body.extent_ = Extent::Sphere;
    body.semi_axes_ = Vector3<double>::Constant(radius);
    return body;
  }

  /// This body with reaction wheels (its J the whole body's, wheels locked).
  /// Throws InvalidInput as Wheels does, naming `prefix`.wheel[i]; a linear
  /// body or a point takes none (`prefix`.wheel).
  RigidBody with_wheels(std::vector<Wheel> wheels, const std::string& prefix = "body") const {
    if (wheels.empty()) return *this;
    if (rotational_dof_ != 3)
      throw InvalidInput(prefix + ".wheel: " + std::string(rotation_description()) + " takes no reaction wheels");
    RigidBody body = *this;
    body.wheels_ = std::make_shared<const Wheels>(inertia_, std::move(wheels), prefix);
    return body;
  }
  bool has_wheels() const { return wheels_ != nullptr; }
  /// The wheels (none: an empty set).
  const Wheels& wheels() const {
    static const Wheels none;
    return wheels_ ? *wheels_ : none;
  }

  double mass() const { return mass_; }
  /// Standard inertia J (the paper's J = tr[J_d] I - J_d).
  const Matrix3<double>& inertia() const { return inertia_; }
  /// J^{-1}; the pseudo-inverse for a linear body, 0 for a point.
  const Matrix3<double>& inertia_inverse() const { return inertia_inverse_; }
  /// Rotational degrees of freedom: 3, 2 for a linear body, 0 for a point.
  int rotational_dof() const { return rotational_dof_; }
  /// What the body is, for messages: "a body with three principal moments",
  /// "a linear body (a zero principal moment)" or "a point mass (no inertia)".
  const char* rotation_description() const {
    return rotational_dof_ == 3   ? "a body with three principal moments"
           : rotational_dof_ == 2 ? "a linear body (a zero principal moment)"
                                  : "a point mass (no inertia)";
  }
  /// A linear body's axis n (body frame, unit): J = I (1 - n n^T). Zero otherwise.
  const Vector3<double>& linear_axis() const { return axis_; }
  /// The momentum w (= 2 J Omega) with what this body cannot have removed:
  /// its component along a linear body's axis, all of it for a point; w
  /// itself, bit for bit, for a body with three moments.
  Vector3<double> admissible_momentum(const Vector3<double>& w) const {
    if (rotational_dof_ == 3) return w;
    if (rotational_dof_ == 0) return Vector3<double>::Zero();
    return w - w.dot(axis_) * axis_;
  }
  /// Whether w is a momentum this body can have up to round-off: what
  /// admissible_momentum removes is at most 1e-12 |w| (a linear body's w
  /// computed from rounded data, or written in a file with 17 digits, keeps
  /// about 1e-16 |w| along the axis; more than 1e-12 is a mistake, not rounding).
  bool admits_momentum(const Vector3<double>& w) const {
    return (w - admissible_momentum(w)).norm() <= 1e-12 * w.norm();
  }
  /// Whether the body frame is a principal frame: J diagonal, its
  /// off-diagonal entries within 8 eps of the largest moment (the round-off of
  /// a sum of ball inertias; user input must be diagonal as written). The
  /// splitting methods (NO_SQUISH, DLM) rotate about the body axes and need it.
  bool has_principal_axes() const {
    const double off = std::max({std::abs(inertia_(0, 1)), std::abs(inertia_(0, 2)), std::abs(inertia_(1, 2)),
                                 std::abs(inertia_(1, 0)), std::abs(inertia_(2, 0)), std::abs(inertia_(2, 1))});
    return off <= 8 * eps * inertia_.diagonal().cwiseAbs().maxCoeff();
  }

  /// The balls, with positions relative to the centre of mass. Empty for a
  /// body given by mass and inertia.
  const std::vector<Ball>& balls() const { return balls_; }

  Extent extent() const { return extent_; }
  /// The semi-axes of a Sphere (r, r, r) or an Ellipsoid (a, b, c); zero otherwise.
  const Vector3<double>& semi_axes() const { return semi_axes_; }
  /// The radius of the smallest sphere about the centre of mass known to
  /// hold the body: max_i |rho_i| + r_i over its balls, the largest
  /// semi-axis, the sphere's radius; 0 for a Point.
  double bounding_radius() const {
    if (extent_ != Extent::Balls) return semi_axes_.maxCoeff();
    double r = 0.0;
    for (const Ball& b : balls_) r = std::max(r, b.position.norm() + b.radius);
    return r;
  }

 private:
  RigidBody(double mass, const Matrix3<double>& inertia, std::vector<Ball> balls)
      : mass_(mass), inertia_(inertia), balls_(std::move(balls)), extent_(Extent::Balls) {
    validate();
  }

  /// A solid shape has three moments > 0: one that rounds to a line or a
  /// point (m r^2 underflowing) is an error, not a linear body.
  void require_three_moments(const char* key) const {
    if (rotational_dof_ != 3)
      throw InvalidInput(std::string(key) + ": the shape's inertia rounds to that of a line or a point");
  }

  static void require_length(double v, const char* key) {
    if (!(std::isfinite(v) && v > 0.0))
      throw InvalidInput(std::string(key) + ": must be a finite number > 0, got " + std::to_string(v));
  }

  void validate() {
    if (!(std::isfinite(mass_) && mass_ > 0.0))
      throw InvalidInput("body.mass: must be a finite number > 0, got " + std::to_string(mass_));
    if (!inertia_.allFinite()) throw InvalidInput("body.inertia: must be finite");
    const double scale = inertia_.cwiseAbs().maxCoeff();
    // Symmetry to a few ulps of the largest entry: the sum in from_balls is
    // exactly symmetric, user input must be symmetric as written.
    if ((inertia_ - inertia_.transpose()).cwiseAbs().maxCoeff() > 8 * eps * scale)
      throw InvalidInput("body.inertia: must be symmetric");
    if (scale == 0.0) {  // a point mass (one ball of radius 0, or balls at one place)
      rotational_dof_ = 0;
      inertia_.setZero();
      inertia_inverse_.setZero();
      return;
    }
    const Eigen::SelfAdjointEigenSolver<Matrix3<double>> es(inertia_);
    const Vector3<double>& l = es.eigenvalues();  // ascending
    if (!(l(0) >= -linear_threshold * l(2)))
      throw InvalidInput("body.inertia: must be positive semi-definite (principal moments " + std::to_string(l(0)) +
                         ", " + std::to_string(l(1)) + ", " + std::to_string(l(2)) + ")");
    if (l(0) <= linear_threshold * l(2)) {
      // Linear: the other two moments are equal (mass on one line), to the
      // same threshold; a test problem's (0, 1, 2) is no body.
      if (l(2) - l(1) > 2 * linear_threshold * l(2))
        throw InvalidInput("body.inertia: principal moments " + std::to_string(l(0)) + ", " + std::to_string(l(1)) +
                           ", " + std::to_string(l(2)) +
                           ": a zero moment is a linear body (mass on one line), whose other two moments are equal");
      const double moment = 0.5 * (l(1) + l(2));
      axis_ = es.eigenvectors().col(0).normalized();
      const Matrix3<double> across = Matrix3<double>::Identity() - axis_ * axis_.transpose();
      inertia_ = moment * across;
      inertia_inverse_ = across / moment;
      rotational_dof_ = 2;
      return;
    }
    // Triangle inequality J1 + J2 >= J3; equality is a lamina (planar point
    // masses), allowed up to round-off of the eigen-decomposition.
    if (require_triangle_ && l(0) + l(1) < l(2) * (1.0 - 64 * eps))
      throw InvalidInput("body.inertia: principal moments " + std::to_string(l(0)) + ", " + std::to_string(l(1)) +
                         ", " + std::to_string(l(2)) +
                         " violate the triangle inequality J1 + J2 >= J3; no mass distribution has them "
                         "(a test problem may waive the check: body.physical = false)");
    inertia_inverse_ = inertia_.inverse();
  }

  /// A principal moment at or below this fraction of the largest is zero
  /// (LAMMPS's fix rigid/small EPSILON).
  static constexpr double linear_threshold = 1e-7;
  static constexpr double eps = std::numeric_limits<double>::epsilon();
  double mass_;
  Matrix3<double> inertia_;
  bool require_triangle_ = true;
  Matrix3<double> inertia_inverse_;
  int rotational_dof_ = 3;
  Vector3<double> axis_ = Vector3<double>::Zero();
  std::vector<Ball> balls_;
  Extent extent_ = Extent::Point;
  Vector3<double> semi_axes_ = Vector3<double>::Zero();
  std::shared_ptr<const Wheels> wheels_;  ///< none: a rigid body (shared: bodies are copied freely)
};

}  // namespace lgvi
