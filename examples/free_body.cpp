// A free rigid body with the quaternion LGVI, using only the installed
// header-only library (find_package(lgvi), target lgvi::lgvi).
//
// Spatial angular momentum is conserved to round-off and |q| stays 1 without
// normalization; the program prints both and exits non-zero if either is
// off by more than 1e-12 (a round-off budget for 1e4 steps).
#include <lgvi/integrate.hpp>

#include <cmath>
#include <cstdio>

int main() {
  using V3 = lgvi::Vector3<double>;
  // The free body of Manchester & Peck: J = diag(1, 2, 3), Omega0 = (pi/10, pi/6, pi/8).
  const double pi = std::acos(-1.0);
  const lgvi::RigidBody body(1.0, lgvi::Matrix3<double>(V3(1.0, 2.0, 3.0).asDiagonal()));
  // The N-body LGVI on the system of this one body (single_body.hpp); its
  // state is a SystemState of one body, read back with body(0).
  lgvi::SingleBody<lgvi::LieGroupVariationalIntegrator, lgvi::NoPotential> integrator(body, {});
  lgvi::SystemState s(lgvi::lift({V3::Zero(), lgvi::Matrix3<double>::Identity(), V3::Zero(),
                                  V3(pi / 10, pi / 6, pi / 8)},
                                 body));
  const V3 l0 = lgvi::angular_momentum(s.body(0));
  double max_dl = 0, max_dq = 0, e0 = 0, max_de = 0;
  lgvi::integrate_n_steps(integrator, s, 0.0, 0.1, 10000, [&](const lgvi::SystemStepInfo& i) {
    const lgvi::RigidBodyState b = i.state.body(0);
    const double e = lgvi::total_energy(b, body, i.evaluation.body(0));
    if (i.k == 0) e0 = e;
    max_de = std::max(max_de, std::abs(e - e0));
    max_dl = std::max(max_dl, (lgvi::angular_momentum(b) - l0).norm() / l0.norm());
    max_dq = std::max(max_dq, std::abs(b.q.norm_error()));
  });
  std::printf("free body, 1e4 steps of h = 0.1: max |dL|/|L| = %.2e, max ||q|-1| = %.2e, max |dE| = %.2e\n", max_dl,
              max_dq, max_de);
  return (max_dl < 1e-12 && max_dq < 1e-12) ? 0 : 1;
}
