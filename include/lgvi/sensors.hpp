// Attitude sensors for a sampled attitude controller: a rate gyro and a star tracker, read at the
// controller's samples t_n = n T (T its period). The controller sees their readings; the dynamics is
// integrated with the true state.
//
// Gyro (a simple discrete form of Farrenkopf's model: the bias at the sample rather than its mean over
// the interval, and without the sigma_u^2 T / 12 of the white variance, negligible while sigma_u T << sigma_v):
//   omega_m,n = omega_n + b_n + (sigma_v / sqrt(T)) N_v,n,     b_{n+1} = b_n + sigma_u sqrt(T) N_u,n,
// with sigma_v the white rate noise density (rad/s/sqrt(Hz): angle random walk), sigma_u the bias's
// random walk density (rad/s^2/sqrt(Hz): rate random walk) and b_0 the initial bias (rad/s), per body
// axis. Star tracker: q_m,n = q_n (x) exp(theta_n / 2), theta_n,i = sigma_i N_i,n, a small rotation in
// body axes with a standard deviation per axis (rad; a tracker's boresight axis is the noisy one).
//
// Every N is a standard normal of (seed, n, stream, axis) from a counter-based generator
// (counter_random.hpp): a reading depends on the sample's number, not on how a run got there, so a run is
// repeatable and the same on any number of threads, in an ensemble on any rank, and across a resume.
#pragma once

#include <lgvi/checkpoint_fields.hpp>
#include <lgvi/counter_random.hpp>
#include <lgvi/error.hpp>
#include <lgvi/s3.hpp>

#include <cmath>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

namespace lgvi {

/// A rate gyro's errors (rad/s/sqrt(Hz), rad/s^2/sqrt(Hz), rad/s). Zero: a perfect gyro.
struct GyroModel {
  double noise_density = 0.0;  ///< sigma_v, white noise on the rate (angle random walk)
  double bias_walk = 0.0;      ///< sigma_u, the bias's random walk (rate random walk)
  Vector3<double> initial_bias = Vector3<double>::Zero();
  std::uint64_t seed = 0;
};

/// A star tracker's attitude noise: one standard deviation per body axis (rad).
struct StarTrackerModel {
  Vector3<double> noise = Vector3<double>::Zero();
  std::uint64_t seed = 0;
};

/// What the controller sees at a sample: the measured attitude and body rate, and the gyro's bias then
/// (the truth behind the rate's error, for analysis).
struct AttitudeMeasurement {
  S3d q;
  Vector3<double> omega = Vector3<double>::Zero();
  Vector3<double> gyro_bias = Vector3<double>::Zero();
};

/// A gyro and/or a star tracker read at the samples n = 0, 1, 2, ... of a controller of period T. A
/// missing sensor reads the truth (no gyro: the true rate; no tracker: the true attitude). Invariant:
/// T > 0 and finite, the models' numbers finite and >= 0 (the bias any finite vector).
class AttitudeSensors {
 public:
  AttitudeSensors() = default;
  AttitudeSensors(std::optional<GyroModel> gyro, std::optional<StarTrackerModel> tracker, double period)
      : gyro_(std::move(gyro)), tracker_(std::move(tracker)), period_(period) {
    if (!(period > 0.0 && std::isfinite(period))) throw InvalidInput("sensors: the sampling period must be > 0");
    if (gyro_ && !(gyro_->noise_density >= 0.0 && std::isfinite(gyro_->noise_density) && gyro_->bias_walk >= 0.0 &&
                   std::isfinite(gyro_->bias_walk) && gyro_->initial_bias.allFinite()))
      throw InvalidInput("sensors: the gyro's densities must be finite and >= 0, its bias finite");
    if (tracker_ && !(tracker_->noise.allFinite() && tracker_->noise.minCoeff() >= 0.0))
      throw InvalidInput("sensors: the star tracker's noise must be finite and >= 0 per axis");
    reset();
  }

  bool has_gyro() const { return gyro_.has_value(); }
  bool has_star_tracker() const { return tracker_.has_value(); }

  /// The readings at sample n of the true attitude q and rate omega (body axes). The gyro's bias is
  /// walked to sample n first (through every sample between, so a skipped sample changes nothing):
  /// samples must come in increasing order (std::logic_error otherwise).
  AttitudeMeasurement measure(std::int64_t n, const S3d& q, const Vector3<double>& omega) {
    if (n < next_) throw std::logic_error("sensors: samples must be read in increasing order");
    AttitudeMeasurement m{q, omega, Vector3<double>::Zero()};
    if (gyro_) {
      const double step = gyro_->bias_walk * std::sqrt(period_);
      for (; bias_at_ < n; ++bias_at_)
        for (int i = 0; i < 3; ++i) bias_(i) += step * normal(gyro_->seed, bias_at_, gyro_bias_stream, i);
      m.gyro_bias = bias_;
      const double white = gyro_->noise_density / std::sqrt(period_);
      for (int i = 0; i < 3; ++i) m.omega(i) = omega(i) + bias_(i) + white * normal(gyro_->seed, n, gyro_rate_stream, i);
    }
    if (tracker_) {
      Vector3<double> theta;
      for (int i = 0; i < 3; ++i) theta(i) = tracker_->noise(i) * normal(tracker_->seed, n, tracker_stream, i);
      m.q = q * S3d::exp(0.5 * theta);  // exp(xi) turns by 2 |xi|
    }
    next_ = n + 1;
    return m;
  }

  /// A checkpoint's fields under `prefix` (checkpoint_fields.hpp): "PREFIX.gyro_bias" (the bias walked
  /// so far, 3 numbers) and "PREFIX.samples" (the sample that bias is at, the next sample that may be
  /// read). The draws themselves are functions of the sample number and need no state.
  void save(CheckpointFields& out, const std::string& prefix) const {
    out.put_f64(prefix + ".gyro_bias", {bias_.x(), bias_.y(), bias_.z()});
    out.put_i64(prefix + ".samples", {bias_at_, next_});
  }
  /// Restores what save(out, prefix) wrote.
  void load(const CheckpointFields& in, const std::string& prefix) {
    const std::vector<double>& b = in.f64(prefix + ".gyro_bias", 3);
    const std::vector<std::int64_t>& n = in.i64(prefix + ".samples", 2);
    if (n[0] < 0 || n[1] < 0 || n[0] > std::max<std::int64_t>(n[1], 0))
      throw InvalidInput("checkpoint field '" + prefix + ".samples' holds sample numbers out of order");
    bias_ = Vector3<double>(b[0], b[1], b[2]);
    bias_at_ = n[0];
    next_ = n[1];
  }

  /// The smallest sample number that may be read next.
  std::int64_t next_sample() const { return next_; }

  /// Back to the start: the initial bias, sample 0 next.
  void reset() {
    bias_ = gyro_ ? gyro_->initial_bias : Vector3<double>::Zero();
    bias_at_ = 0;
    next_ = 0;
  }

 private:
  static constexpr std::size_t gyro_rate_stream = 0, gyro_bias_stream = 1, tracker_stream = 2;
  static double normal(std::uint64_t seed, std::int64_t n, std::size_t stream, int axis) {
    return counter_random::normal01(seed, n, stream, static_cast<std::size_t>(axis));
  }

  std::optional<GyroModel> gyro_;
  std::optional<StarTrackerModel> tracker_;
  double period_ = 1.0;
  Vector3<double> bias_ = Vector3<double>::Zero();
  std::int64_t bias_at_ = 0;  ///< the sample whose bias bias_ is
  std::int64_t next_ = 0;     ///< the smallest sample number that may be read next
};

}  // namespace lgvi
