// Lennard-Jones between the balls (sites) of different bodies: rigid
// molecules and granular models. A pair kernel on PairInteraction
// (pair_interaction.hpp), which finds the pairs and sums the forces.
//
//   u(r) = 4 eps ((sigma/r)^12 - (sigma/r)^6) - V_c,   V_c = 4 eps ((sigma/r_c)^12 - (sigma/r_c)^6),
//
// for r < r_c: the energy shifted to zero at the cutoff (forces unchanged;
// LAMMPS's pair_modify shift yes). With d = X_j - X_i, the force on site i is
//   f_i = -24 eps (2 (sigma/r)^12 - (sigma/r)^6) d / r^2.
#pragma once

#include <lgvi/error.hpp>
#include <lgvi/forces/pair_interaction.hpp>

#include <cmath>

namespace lgvi {

/// The Lennard-Jones pair kernel (a PairKernel).
class LennardJonesKernel {
 public:
  /// Throws InvalidInput naming interaction.epsilon, .sigma or .cutoff unless
  /// each is a finite number > 0.
  LennardJonesKernel(double epsilon, double sigma, double cutoff)
      : eps_(epsilon), sigma2_(sigma * sigma), minus_24_eps_(-24.0 * epsilon), four_eps_(4.0 * epsilon),
        cutoff_(cutoff), cutoff2_(cutoff * cutoff) {
    if (!(std::isfinite(epsilon) && epsilon > 0.0))
      throw InvalidInput("interaction.epsilon: must be a finite number > 0");
    if (!(std::isfinite(sigma) && sigma > 0.0)) throw InvalidInput("interaction.sigma: must be a finite number > 0");
    if (!(std::isfinite(cutoff) && cutoff > 0.0))
      throw InvalidInput("interaction.cutoff: must be a finite number > 0 (typically 2.5 sigma)");
    const double sr6 = std::pow(sigma2_ / (cutoff * cutoff), 3);
    shift_ = 4.0 * eps_ * (sr6 * sr6 - sr6);
  }

  double cutoff() const { return cutoff_; }
  double cutoff2() const { return cutoff2_; }
  double epsilon() const { return eps_; }
  double sigma() const { return std::sqrt(sigma2_); }
  /// V(r_c) of the unshifted potential, subtracted from every pair's energy.
  double shift() const { return shift_; }

  /// coef = -24 eps (2 (sigma/r)^12 - (sigma/r)^6) / r^2 and the shifted energy.
  [[gnu::always_inline]] PairTerms operator()(double r2) const {
    const double sr2 = sigma2_ / r2;
    const double sr6 = sr2 * sr2 * sr2;
    const double sr12 = sr6 * sr6;
    return {minus_24_eps_ * (2.0 * sr12 - sr6) / r2, four_eps_ * (sr12 - sr6) - shift_};
  }

 private:
  double eps_, sigma2_, minus_24_eps_, four_eps_, cutoff_, cutoff2_, shift_ = 0.0;
};

/// Lennard-Jones between the sites of different bodies (`[interaction] kind =
/// "lennard-jones"`).
class LennardJones : public PairInteraction<LennardJonesKernel> {
 public:
  /// `skin`: the Verlet lists hold pairs within cutoff + skin; negative: 0.3
  /// sigma (LAMMPS's default).
  LennardJones(const System& sys, double epsilon, double sigma, double cutoff, Parallelism par = {},
               double skin = -1.0)
      : PairInteraction(sys, LennardJonesKernel(epsilon, sigma, cutoff), par, skin < 0.0 ? 0.3 * sigma : skin) {}

  double epsilon() const { return kernel().epsilon(); }
  double sigma() const { return kernel().sigma(); }
};

}  // namespace lgvi
