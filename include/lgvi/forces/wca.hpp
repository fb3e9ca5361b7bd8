// Weeks-Chandler-Andersen between the balls (sites) of different bodies: the
// repulsive part of Lennard-Jones, a soft sphere of diameter ~ sigma. A pair
// kernel on PairInteraction (pair_interaction.hpp).
//
//   u(r) = 4 eps ((sigma/r)^12 - (sigma/r)^6) + eps   for r < r_c = 2^(1/6) sigma,
//
// the minimum of Lennard-Jones, so that u(r_c) = 0 and the force, zero there
// too, is continuous. With d = X_j - X_i, the force on site i is
//   f_i = -24 eps (2 (sigma/r)^12 - (sigma/r)^6) d / r^2,
// the same IEEE operations as Lennard-Jones's (forces/lennard_jones.hpp): a
// pair's force equals LJ's with the same cutoff bit for bit.
#pragma once

#include <lgvi/error.hpp>
#include <lgvi/forces/pair_interaction.hpp>

#include <cmath>

namespace lgvi {

/// The WCA pair kernel (a PairKernel).
class WcaKernel {
 public:
  /// Throws InvalidInput naming interaction.epsilon or .sigma unless each is
  /// a finite number > 0.
  WcaKernel(double epsilon, double sigma)
      : eps_(epsilon), sigma_(sigma), sigma2_(sigma * sigma), minus_24_eps_(-24.0 * epsilon),
        four_eps_(4.0 * epsilon), cutoff_(std::pow(2.0, 1.0 / 6.0) * sigma), cutoff2_(cutoff_ * cutoff_) {
    if (!(std::isfinite(epsilon) && epsilon > 0.0))
      throw InvalidInput("interaction.epsilon: must be a finite number > 0");
    if (!(std::isfinite(sigma) && sigma > 0.0)) throw InvalidInput("interaction.sigma: must be a finite number > 0");
  }

  double cutoff() const { return cutoff_; }
  double cutoff2() const { return cutoff2_; }
  double epsilon() const { return eps_; }
  double sigma() const { return sigma_; }

  [[gnu::always_inline]] PairTerms operator()(double r2) const {
    const double sr2 = sigma2_ / r2;
    const double sr6 = sr2 * sr2 * sr2;
    const double sr12 = sr6 * sr6;
    return {minus_24_eps_ * (2.0 * sr12 - sr6) / r2, four_eps_ * (sr12 - sr6) + eps_};
  }

 private:
  double eps_, sigma_, sigma2_, minus_24_eps_, four_eps_, cutoff_, cutoff2_;
};

/// WCA between the sites of different bodies (`[interaction] kind = "wca"`).
class WeeksChandlerAndersen : public PairInteraction<WcaKernel> {
 public:
  /// `skin`: the Verlet lists hold pairs within 2^(1/6) sigma + skin;
  /// negative: 0.3 sigma (as Lennard-Jones).
  WeeksChandlerAndersen(const System& sys, double epsilon, double sigma, Parallelism par = {}, double skin = -1.0)
      : PairInteraction(sys, WcaKernel(epsilon, sigma), par, skin < 0.0 ? 0.3 * sigma : skin) {}

  double epsilon() const { return kernel().epsilon(); }
  double sigma() const { return kernel().sigma(); }
};

}  // namespace lgvi
