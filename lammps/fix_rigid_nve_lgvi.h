// fix rigid/nve/lgvi (style name kept internally as rigid/nve/lgvi/small):
// the quaternion Lie group variational integrator of Shen & Leok for LAMMPS's
// rigid bodies, on fix rigid/small's bodies, communication and restart.
//
// The step, in space-frame variables (L the angular momentum, tau the torque,
// R = pi(q) the body-to-space rotation, J = diag(I1, I2, I3) the principal
// moments, h the time step):
//   v += (h/2m) F;  x += h v;  L += (h/2) tau;                (as rigid/small)
//   Pi = R^T L;  solve  f_s J f_v + f_v x J f_v = (h/2) Pi  for the unit
//   quaternion f (lgvi's RotationSolver, Newton in the Cayley chart);
//   q <- q f  (a product of unit quaternions: no normalisation);
//   forces and torques at the new configuration;
//   v += (h/2m) F;  L += (h/2) tau.                            (as rigid/small)
// This is lgvi's Hamiltonian-form step (include/lgvi/lgvi.hpp) with w = 2 Pi:
// there g(f) = (h/4)(w0 + h M0) = (h/2)(Pi0 + (h/2) M0), and
// w1 = pi(f)^T (w0 + h M0) + h M1, i.e. R1 Pi1 = R0 (Pi0 + (h/2) M0) + (h/2) R1 M1:
// L is unchanged by the rotation substep, so only the quaternion update of
// rigid/small's initial_integrate (Richardson iteration + normalisation) is
// replaced. Linear bodies (one principal moment set to 0 by rigid/small) are
// rotated by the closed-form root without rotation about their axis; their
// angular velocity about it stays 0, as in rigid/small.
//
// Keywords: those of rigid/small that do not change the integrator (molecule
// or custom bodies, infile, reinit, mol, gravity); langevin and the
// Nose-Hoover keywords (temp, iso, aniso, x, y, z, couple, dilate, tparam,
// pchain) are refused, as are run_style respa and 2d. fix_modify: tolerance
// (relative residual of the rotation solve, default 4 eps) and
// max_iterations (default 50). Global vector (3): Newton iterations of the
// last step summed over bodies, the most one body needed, and the largest
// ||q| - 1| over bodies after it.
//
// Part of lgvi, under the GNU General Public License version 2 (lammps/LICENSE),
// as it links LAMMPS.
#ifdef FIX_CLASS
// clang-format off
FixStyle(rigid/nve/lgvi,FixRigidNVELgvi);
FixStyle(rigid/nve/lgvi/small,FixRigidNVELgvi);
// clang-format on
#else

#ifndef LGVI_LAMMPS_FIX_RIGID_NVE_LGVI_H
#define LGVI_LAMMPS_FIX_RIGID_NVE_LGVI_H

#include "fix_rigid_small.h"

#include <lgvi/rotation_solver.hpp>

namespace LAMMPS_NS {

class FixRigidNVELgvi : public FixRigidSmall {
 public:
  /// The style string every instance carries, whichever name created it:
  /// compute rigid/local, erotate/rigid and ke/rigid recognise rigid/small's
  /// body layout by "rigid/" and "/small" in it.
  static constexpr const char* canonical_style = "rigid/nve/lgvi/small";

  FixRigidNVELgvi(class LAMMPS*, int, char**);
  void init() override;
  void initial_integrate(int) override;
  int modify_param(int, char**) override;
  double compute_vector(int) override;

 private:
  /// Stops with LAMMPS's error for a keyword this fix refuses; returns narg.
  static int refuse_unsupported_keywords(class LAMMPS* lmp, int narg, char** arg);
  /// One body's rotation substep (the file comment); false if the solve failed
  /// (message in `failure`).
  bool rotate(Body& b, int& iterations, std::string& failure) const;

  lgvi::SolverOptions solver_options_;
  long long last_iterations_ = 0;  ///< this rank's sum over its bodies, last step
  int last_worst_iterations_ = 0;  ///< this rank's most iterations of one body
  double last_norm_error_ = 0.0;   ///< this rank's largest ||q| - 1|
};

}  // namespace LAMMPS_NS

#endif
#endif
