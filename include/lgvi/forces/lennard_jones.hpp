// Lennard-Jones between the balls (sites) of different bodies: rigid
// molecules and granular models. A pair kernel on PairInteraction
// (pair_interaction.hpp), which finds the pairs and sums the forces.
//
//   u(r) = 4 eps ((sigma/r)^12 - (sigma/r)^6) - V_c,   V_c = 4 eps ((sigma/r_c)^12 - (sigma/r_c)^6),
//
// for r < r_c: the energy shifted to zero at the cutoff (forces unchanged;
// LAMMPS's pair_modify shift yes). With d = X_j - X_i, the force on site i is
//   f_i = -24 eps (2 (sigma/r)^12 - (sigma/r)^6) d / r^2.
// With site types (LAMMPS's atom types), eps and sigma are those of the
// pair's types (eps_ij, sigma_ij, V_c,ij; one cutoff r_c for every pair):
// LennardJonesTypesKernel, the same operations per pair.
#pragma once

#include <lgvi/error.hpp>
#include <lgvi/forces/pair_interaction.hpp>

#include <cmath>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

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

/// The Lennard-Jones pair kernel of typed sites (a TypedPairKernel): per pair
/// of types (i, j) its eps_ij and sigma_ij, the operations of
/// LennardJonesKernel's with them (so a table of equal entries gives its
/// results to the bit). The table is shared by the kernel's copies.
class LennardJonesTypesKernel {
 public:
  /// `epsilon`, `sigma`: T x T symmetric tables, row-major (entry T i + j for
  /// types i, j, 0-based). Throws InvalidInput unless each entry is a finite
  /// number > 0 and the tables are symmetric.
  LennardJonesTypesKernel(std::uint32_t types, const std::vector<double>& epsilon, const std::vector<double>& sigma,
                          double cutoff)
      : types_(types), cutoff_(cutoff), cutoff2_(cutoff * cutoff) {
    const std::size_t n = std::size_t{types} * types;
    if (types < 1 || epsilon.size() != n || sigma.size() != n)
      throw InvalidInput("interaction: the pair coefficients need a " + std::to_string(types) + " x " +
                         std::to_string(types) + " table");
    if (!(std::isfinite(cutoff) && cutoff > 0.0))
      throw InvalidInput("interaction.cutoff: must be a finite number > 0 (typically 2.5 sigma)");
    auto table = std::make_shared<std::vector<Coefficients>>(n);
    for (std::uint32_t i = 0; i < types; ++i)
      for (std::uint32_t j = 0; j < types; ++j) {
        const std::size_t at = std::size_t{types} * i + j, mirror = std::size_t{types} * j + i;
        const double eps = epsilon[at], sig = sigma[at];
        const std::string name = "interaction.pair (types " + std::to_string(i + 1) + ", " + std::to_string(j + 1) + ")";
        if (!(std::isfinite(eps) && eps > 0.0 && std::isfinite(sig) && sig > 0.0))
          throw InvalidInput(name + ": epsilon and sigma must be finite numbers > 0");
        if (eps != epsilon[mirror] || sig != sigma[mirror]) throw InvalidInput(name + ": the table must be symmetric");
        // (As LennardJonesKernel forms them, from eps and sigma^2.)
        const double sigma2 = sig * sig;
        const double sr6 = std::pow(sigma2 / (cutoff * cutoff), 3);
        (*table)[at] = {-24.0 * eps, 4.0 * eps, sigma2, 4.0 * eps * (sr6 * sr6 - sr6)};
      }
    table_ = table->data();
    owner_ = std::move(table);
  }

  double cutoff() const { return cutoff_; }
  double cutoff2() const { return cutoff2_; }
  std::uint32_t types() const { return types_; }
  /// eps and sigma of the pair of types (i, j), 0-based.
  double epsilon(std::uint32_t i, std::uint32_t j) const { return table_[types_ * i + j].four_eps / 4.0; }
  double sigma(std::uint32_t i, std::uint32_t j) const { return std::sqrt(table_[types_ * i + j].sigma2); }

  /// The pair `pair` = T t_i + t_j's coef and shifted energy (LennardJonesKernel's).
  [[gnu::always_inline]] PairTerms operator()(double r2, std::uint32_t pair) const {
    const Coefficients& c = table_[pair];
    const double sr2 = c.sigma2 / r2;
    const double sr6 = sr2 * sr2 * sr2;
    const double sr12 = sr6 * sr6;
    return {c.minus_24_eps * (2.0 * sr12 - sr6) / r2, c.four_eps * (sr12 - sr6) - c.shift};
  }

 private:
  struct Coefficients {
    double minus_24_eps, four_eps, sigma2, shift;
  };
  std::uint32_t types_;
  double cutoff_, cutoff2_;
  std::shared_ptr<const std::vector<Coefficients>> owner_;
  const Coefficients* table_ = nullptr;
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

/// Lennard-Jones between typed sites of different bodies: per pair of site
/// types its own eps and sigma (`[[interaction.pair]]`, LAMMPS's pair_coeff
/// i j with pair_modify mix).
class LennardJonesTypes : public PairInteraction<LennardJonesTypesKernel> {
 public:
  /// `skin`: the Verlet lists hold pairs within cutoff + skin (>= 0).
  LennardJonesTypes(const System& sys, const LennardJonesTypesKernel& kernel, double skin, Parallelism par = {})
      : PairInteraction(sys, kernel, par, skin) {}
};

}  // namespace lgvi
