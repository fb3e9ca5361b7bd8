// The simulation box: free space, or an orthogonal box [lower, upper) that is
// periodic along any combination of the three axes.
//
// Along a periodic axis k of length L_k = upper_k - lower_k, space is a circle:
// a body at x and at x + n L_k e_k (n an integer) is the same body. lgvi keeps
// each centre of mass unwrapped in the state (the continuous path the
// integrator moves, so that the dynamics never jumps) and wraps it only to
// write it: x = wrapped + image * L, wrapped in [lower, upper). Pairs of sites
// interact through their minimum image: the separation d reduced along each
// periodic axis to d_k - L_k round(d_k / L_k), in [-L_k/2, L_k/2]. With the
// interaction's reach (cutoff + skin) below half the shortest periodic
// length, a pair has at most one image within reach, so that the lists and
// the sums see each pair once (checked where the box meets an interaction).
// The pair interactions place each body's sites about its centre of mass
// wrapped into the box (InteractionSites::place_wrapped), a function of the
// state alone, so that only the pairs that straddle a face need reducing.
//
// Along a non-periodic axis space is open: bodies move freely beyond lower and
// upper, and no separation is reduced (lower and upper only bound the box that
// the exports draw).
//
// The reduction is antisymmetric to the bit: round-to-nearest (ties to even)
// is odd, so the image of -d is exactly minus the image of d, and a pair's
// two forces cancel exactly as in free space (Newton's third law to the bit:
// the total linear momentum is conserved to round-off).
//
// A triclinic box would add the tilt factors (xy, xz, yz) here, with the
// minimum image taken in the box's fractional coordinates; the neighbour
// lists (forces/neighbour_lists.hpp) bin sites in fractional coordinates
// already along periodic axes, so only this class and the exports would change.
#pragma once

#include <lgvi/error.hpp>
#include <lgvi/s3.hpp>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <limits>
#include <string>

namespace lgvi {

/// An orthogonal box, periodic along any of its axes (the comment above).
/// Invariant: along a periodic axis, lower and upper are finite and lower <
/// upper; a default Box is free space (no periodic axis).
class Box {
 public:
  /// Free space.
  Box() = default;
  /// [lower, upper), periodic along the axes where `periodic` is true. Throws
  /// InvalidInput ("box.upper[k]: ...") unless lower and upper are finite and
  /// lower < upper along every axis.
  Box(const Vector3<double>& lower, const Vector3<double>& upper, const std::array<bool, 3>& periodic)
      : lower_(lower), upper_(upper), periodic_(periodic) {
    for (int k = 0; k < 3; ++k) {
      auto fail = [k](const char* key, const char* what) {
        std::string message = key;
        message += '[';
        message += static_cast<char>('0' + k);
        message += "]: ";
        message += what;
        throw InvalidInput(message);
      };
      if (!std::isfinite(lower(k))) fail("box.lower", "must be a finite number");
      if (!(std::isfinite(upper(k)) && upper(k) > lower(k))) fail("box.upper", "must be a finite number > box.lower");
      const double length = upper(k) - lower(k);
      if (!std::isfinite(length)) fail("box.upper", "the box is wider than a double can hold");
      below_upper_(k) = std::nextafter(upper(k), lower(k));
      if (periodic[static_cast<std::size_t>(k)]) {
        length_(k) = length;
        inverse_length_(k) = 1.0 / length;
        plain_bound_(k) = 0.5 * length * (1.0 - 0x1p-20);
        plain_radius2_ = std::min(plain_radius2_, plain_bound_(k) * plain_bound_(k));
      }
    }
    any_periodic_ = periodic[0] || periodic[1] || periodic[2];
  }

  /// Whether this is the default box (free space, no bounds given).
  bool free_space() const { return !(upper_(0) > lower_(0)); }
  bool any_periodic() const { return any_periodic_; }
  bool periodic(int k) const { return periodic_[static_cast<std::size_t>(k)]; }
  const std::array<bool, 3>& periodic() const { return periodic_; }
  const Vector3<double>& lower() const { return lower_; }
  const Vector3<double>& upper() const { return upper_; }
  /// L_k along a periodic axis, 0 along an open one.
  const Vector3<double>& periodic_length() const { return length_; }
  /// 1 / L_k along a periodic axis, 0 along an open one.
  const Vector3<double>& inverse_periodic_length() const { return inverse_length_; }
  /// The shortest periodic length (infinity without a periodic axis).
  double shortest_periodic_length() const {
    double l = std::numeric_limits<double>::infinity();
    for (int k = 0; k < 3; ++k)
      if (periodic(k)) l = std::min(l, length_(k));
    return l;
  }

  /// The separation d reduced to its minimum image: d_k - L_k round(d_k / L_k)
  /// along each periodic axis, unchanged along open ones (there L_k = 0 and
  /// 1/L_k is stored as 0, so the same operations leave d_k exactly as it
  /// is). Odd: minimum_image(-d) = -minimum_image(d) exactly.
  Vector3<double> minimum_image(const Vector3<double>& d) const {
    Vector3<double> r = d;
    for (int k = 0; k < 3; ++k) r(k) = reduce(d(k), k);
    return r;
  }
  /// One component of minimum_image.
  double reduce(double d, int k) const { return d - length_(k) * image(d, k); }
  /// Per axis, a bound on |d_k| within which d_k is its own minimum image:
  /// reduce(d_k, k) is d_k + 0.0 to the bit (the reduction turns -0 into +0).
  /// Just below L_k / 2 along a periodic axis, so that d_k / L_k, rounded, is
  /// below 1/2 however it rounds; infinity along an open one.
  const Vector3<double>& plain_bound() const { return plain_bound_; }
  /// The smallest plain_bound()^2 (as rounded: b * b), infinity in free
  /// space: a separation d whose (dx^2 + dy^2) + dz^2, rounded, is below it
  /// has no component beyond plain_bound() (if |d_k| > b_k, the rounded
  /// squares and their rounded sum are at least b_k * b_k, rounding being
  /// monotonic). One test on r^2 where a pair loop has it anyway.
  double plain_radius2() const { return plain_radius2_; }
  /// Whether a component of d is beyond plain_bound(): only then is its
  /// minimum image another than d + 0.0, and reduce() needed.
  /// (The three tests are or-ed bitwise, as ints: no branch per component in the pair loops.)
  bool beyond_plain(double dx, double dy, double dz) const {
    return (static_cast<int>(std::fabs(dx) > plain_bound_(0)) | static_cast<int>(std::fabs(dy) > plain_bound_(1)) |
            static_cast<int>(std::fabs(dz) > plain_bound_(2))) != 0;
  }
  /// d as its minimum image where a component is beyond plain_bound()
  /// (reduce()'s operations, so its bits), else left as it is (the same
  /// up to the sign of a zero); whether an image other than 0 was taken
  /// along some axis (the pair is across a period).
  bool reduce_beyond_plain(double& dx, double& dy, double& dz) const {
    if (!beyond_plain(dx, dy, dz)) return false;
    const double nx = image(dx, 0), ny = image(dy, 1), nz = image(dz, 2);
    dx -= length_(0) * nx;
    dy -= length_(1) * ny;
    dz -= length_(2) * nz;
    return (nx != 0.0) | (ny != 0.0) | (nz != 0.0);
  }
  /// round(d_k / L_k) (as reduce computes it: reduce(d, k) = d - L_k
  /// image(d, k)); +-0 along an open axis.
  double image(double d, int k) const { return nearest_integer(d * inverse_length_(k)); }

  /// std::nearbyint(x) in the default rounding mode (to nearest, ties to
  /// even), sign of zero included, without a call into libm on the pair
  /// loop's path (x86-64 without SSE4.1 has no rounding instruction): for
  /// |x| < 2^51, adding and subtracting 1.5 * 2^52 rounds x to an integer
  /// exactly as nearbyint does (the sum's unit in the last place is 1), and
  /// copysign restores -0 for x in (-0.5, -0]; beyond, and for NaN and
  /// infinities, nearbyint itself.
  static double nearest_integer(double x) {
    constexpr double shift = 6755399441055744.0;  // 1.5 * 2^52
    if (!(std::fabs(x) < 2251799813685248.0)) return std::nearbyint(x);  // 2^51
    return std::copysign((x + shift) - shift, x);
  }

  /// The volume L_x L_y L_z of a box periodic along every axis (0 if one is open).
  double volume() const { return length_.prod(); }

  /// The fractional coordinate of x_k along periodic axis k, (x_k - lower_k) / L_k
  /// less its floor: in [0, 1], 1 only where rounding lifts a value just below
  /// an integer (the cell lists clamp their index); NaN for x_k not finite.
  double fraction(double x_k, int k) const {
    const double f = (x_k - lower_(k)) * inverse_length_(k);
    return f - std::floor(f);
  }

  /// The image count of position x along each periodic axis, n_k =
  /// floor((x_k - lower_k) / L_k) (0 along open axes), and x wrapped into
  /// the box, x - n L, in [lower, upper) along periodic axes. A coordinate
  /// in (lower, upper) already is its own wrap, with image 0 (most are, at
  /// every step: the test is all they cost; lower itself takes the full
  /// path, which turns -0 into +0 at lower = 0). A coordinate 2^52 or more box
  /// lengths away (where rounding has lost its place in the box) or not
  /// finite is left as it is, with image 0.
  struct Wrapped {
    Vector3<double> x;
    std::array<std::int64_t, 3> image{};
  };
  Wrapped wrap(const Vector3<double>& x) const {
    Wrapped w{x, {}};
    for (int k = 0; k < 3; ++k) {
      if (!periodic(k) || (x(k) > lower_(k) && x(k) < upper_(k)) || !std::isfinite(x(k))) continue;
      double n = std::floor((x(k) - lower_(k)) * inverse_length_(k));
      if (!(std::abs(n) < 0x1p52)) continue;
      double v = x(k) - n * length_(k);
      // Rounding can leave v just outside [lower, upper): one more turn.
      if (v >= upper_(k)) {
        n += 1.0;
        v = x(k) - n * length_(k);
      } else if (v < lower_(k)) {
        n -= 1.0;
        v = x(k) - n * length_(k);
      }
      w.x(k) = std::clamp(v, lower_(k), below_upper_(k));
      w.image[static_cast<std::size_t>(k)] = static_cast<std::int64_t>(n);
    }
    return w;
  }

 private:
  Vector3<double> lower_ = Vector3<double>::Zero(), upper_ = Vector3<double>::Zero();
  std::array<bool, 3> periodic_{false, false, false};
  bool any_periodic_ = false;
  Vector3<double> length_ = Vector3<double>::Zero(), inverse_length_ = Vector3<double>::Zero();
  Vector3<double> plain_bound_ = Vector3<double>::Constant(std::numeric_limits<double>::infinity());
  double plain_radius2_ = std::numeric_limits<double>::infinity();
  Vector3<double> below_upper_ = Vector3<double>::Zero();  ///< the largest double below upper, per axis (wrap)
};

}  // namespace lgvi
