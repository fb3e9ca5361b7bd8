// fix rigid/nve/lgvi: the header's comment says what it computes and why.
// Part of lgvi, under the GNU General Public License version 2 (lammps/LICENSE).
#include "fix_rigid_nve_lgvi.h"

#include "atom.h"
#include "comm.h"
#include "domain.h"
#include "error.h"
#include "rigid_const.h"
#include "update.h"
#include "utils.h"

#include <lgvi/error.hpp>
#include <lgvi/s3.hpp>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <string>

using namespace LAMMPS_NS;

namespace {

/// rigid/small's keywords and how many words each takes, keyword included
/// (its constructor has already checked the syntax).
struct Keyword {
  const char* name;
  int words;
  bool supported;
};
constexpr Keyword keywords[] = {
    {"infile", 2, true},  {"reinit", 2, true}, {"mol", 2, true},    {"gravity", 2, true},
    {"langevin", 5, false}, {"temp", 4, false}, {"iso", 4, false},    {"aniso", 4, false},
    {"x", 4, false},      {"y", 4, false},      {"z", 4, false},      {"couple", 2, false},
    {"dilate", 2, false}, {"tparam", 4, false}, {"pchain", 2, false},
};

}  // namespace

// The keywords are checked before rigid/small's constructor reads them: it
// refuses some of them by style name, with a message about its own syntax.
FixRigidNVELgvi::FixRigidNVELgvi(LAMMPS* lmp, int narg, char** arg)
    : FixRigidSmall(lmp, refuse_unsupported_keywords(lmp, narg, arg), arg) {
  delete[] style;
  style = utils::strdup(canonical_style);
  vector_flag = 1;
  size_vector = 3;
  global_freq = 1;
  extvector = 0;
}

int FixRigidNVELgvi::refuse_unsupported_keywords(LAMMPS* lmp, int narg, char** arg) {
  Error* error = lmp->error;
  if (narg < 4) return narg;  // rigid/small's constructor says what is missing
  int iarg = std::strcmp(arg[3], "custom") == 0 ? 5 : 4;
  while (iarg < narg) {
    const Keyword* k = std::find_if(std::begin(keywords), std::end(keywords),
                                    [&](const Keyword& w) { return std::strcmp(w.name, arg[iarg]) == 0; });
    if (k == std::end(keywords)) error->all(FLERR, std::string("Illegal fix rigid/nve/lgvi keyword ") + arg[iarg]);
    if (!k->supported) {
      const std::string why = std::strcmp(k->name, "langevin") == 0
                                  ? "its random and friction forces are not part of this integrator; "
                                    "thermostat with a separate fix, or use fix rigid/small"
                                  : "it belongs to the Nose-Hoover rigid fixes (rigid/nvt/small, rigid/npt/small, "
                                    "rigid/nph/small); fix rigid/nve/lgvi integrates at constant energy";
      error->all(FLERR, std::string("Fix rigid/nve/lgvi does not support keyword ") + k->name + ": " + why);
    }
    iarg += k->words;
  }
  return narg;
}

void FixRigidNVELgvi::init() {
  FixRigidSmall::init();
  if (utils::strmatch(update->integrate_style, "^respa"))
    error->all(FLERR, "Fix rigid/nve/lgvi does not support run_style respa (its step is not split in levels); "
                      "use run_style verlet");
  if (domain->dimension == 2)
    error->all(FLERR, "Fix rigid/nve/lgvi is not available in 2d (untested there); use fix rigid/small");
}

int FixRigidNVELgvi::modify_param(int narg, char** arg) {
  if (std::strcmp(arg[0], "tolerance") == 0) {
    if (narg < 2) error->all(FLERR, "Illegal fix_modify tolerance: give a relative tolerance, e.g. 1e-15");
    const double tolerance = utils::numeric(FLERR, arg[1], false, lmp);
    if (!(tolerance > 0.0) || !(tolerance < 1e-3))
      error->all(FLERR, "Fix_modify tolerance of fix rigid/nve/lgvi must be in (0, 1e-3): it is the solve's "
                        "relative residual (default 4 eps = 8.9e-16)");
    solver_options_.tolerance = tolerance;
    return 2;
  }
  if (std::strcmp(arg[0], "max_iterations") == 0) {
    if (narg < 2) error->all(FLERR, "Illegal fix_modify max_iterations: give a count, e.g. 50");
    const int count = utils::inumeric(FLERR, arg[1], false, lmp);
    if (count < 1) error->all(FLERR, "Fix_modify max_iterations of fix rigid/nve/lgvi must be >= 1 (default 50)");
    solver_options_.max_iterations = count;
    return 2;
  }
  return FixRigidSmall::modify_param(narg, arg);
}

bool FixRigidNVELgvi::rotate(Body& b, int& iterations, std::string& failure) const {
  using Vec = lgvi::Vector3<double>;
  const Vec L(b.angmom[0], b.angmom[1], b.angmom[2]);
  // Pi = R^T L: the rows of R^T are the body axes in space coordinates.
  const Vec pi(Vec(b.ex_space[0], b.ex_space[1], b.ex_space[2]).dot(L),
               Vec(b.ey_space[0], b.ey_space[1], b.ey_space[2]).dot(L),
               Vec(b.ez_space[0], b.ez_space[1], b.ez_space[2]).dot(L));
  const Vec moments(b.inertia[0], b.inertia[1], b.inertia[2]);
  const Vec rhs = dtq * pi;  // dtq = h/2
  // Start from the first-order root u = J^+ b of J u + u x J u = (1 + |u|^2) b.
  Vec u;
  for (int k = 0; k < 3; ++k) u(k) = moments(k) > 0.0 ? rhs(k) / moments(k) : 0.0;
  lgvi::S3d f = lgvi::S3d(1.0, u.x(), u.y(), u.z()).normalized();
  lgvi::SolveReport report;
  try {
    lgvi::RotationSolver::for_principal_moments(moments, solver_options_).solve(rhs, f, report);
  } catch (const lgvi::StepFailure& e) {
    failure = e.what();
    if (!e.hint().empty()) failure += "; " + e.hint();
    return false;
  } catch (const lgvi::InvalidInput& e) {
    failure = e.what();
    return false;
  }
  iterations = report.iterations;
  const lgvi::S3d q0(b.quat[0], b.quat[1], b.quat[2], b.quat[3]);
  const lgvi::S3d q1 = q0.times_near_identity(f);
  b.quat[0] = q1.w();
  for (int k = 0; k < 3; ++k) b.quat[k + 1] = q1.vec()(k);
  const lgvi::Matrix3<double> r = q1.matrix();
  for (int k = 0; k < 3; ++k) {
    b.ex_space[k] = r(k, 0);
    b.ey_space[k] = r(k, 1);
    b.ez_space[k] = r(k, 2);
  }
  // omega = R J^+ R^T L at the new attitude (0 about a zero moment, as rigid/small).
  Vec w_body;
  for (int k = 0; k < 3; ++k) w_body(k) = moments(k) > 0.0 ? r.col(k).dot(L) / moments(k) : 0.0;
  const Vec omega = r * w_body;
  for (int k = 0; k < 3; ++k) b.omega[k] = omega(k);
  return true;
}

void FixRigidNVELgvi::initial_integrate(int vflag) {
  long long iterations = 0;
  int worst = 0;
  double norm_error = 0.0;
  for (int ibody = 0; ibody < nlocal_body; ++ibody) {
    Body& b = body[ibody];
    const double dtfm = dtf / b.mass;
    for (int k = 0; k < 3; ++k) {
      b.vcm[k] += dtfm * b.fcm[k];
      b.xcm[k] += dtv * b.vcm[k];
      b.angmom[k] += dtf * b.torque[k];
    }
    int body_iterations = 0;
    std::string failure;
    if (!rotate(b, body_iterations, failure))
      error->one(FLERR, "Fix rigid/nve/lgvi: the rotation of the body of atom ID " +
                            std::to_string(static_cast<long long>(atom->tag[b.ilocal])) + " failed at step " +
                            std::to_string(static_cast<long long>(update->ntimestep)) + ": " + failure);
    iterations += body_iterations;
    worst = std::max(worst, body_iterations);
    const double norm = std::sqrt(b.quat[0] * b.quat[0] + b.quat[1] * b.quat[1] + b.quat[2] * b.quat[2] +
                                  b.quat[3] * b.quat[3]);
    norm_error = std::max(norm_error, std::abs(norm - 1.0));
  }
  last_iterations_ = iterations;
  last_worst_iterations_ = worst;
  last_norm_error_ = norm_error;

  // As rigid/small: the virial set up before set_xv, the bodies' new state
  // sent to the ranks that hold their atoms as ghosts, the atoms placed.
  v_init(vflag);
  commflag = RigidConst::INITIAL;
  comm->forward_comm_fix(this, 26);
  set_xv();
}

double FixRigidNVELgvi::compute_vector(int n) {
  double local = 0.0;
  double global = 0.0;
  switch (n) {
    case 0:
      local = static_cast<double>(last_iterations_);
      MPI_Allreduce(&local, &global, 1, MPI_DOUBLE, MPI_SUM, world);
      return global;
    case 1:
      local = last_worst_iterations_;
      MPI_Allreduce(&local, &global, 1, MPI_DOUBLE, MPI_MAX, world);
      return global;
    case 2:
      local = last_norm_error_;
      MPI_Allreduce(&local, &global, 1, MPI_DOUBLE, MPI_MAX, world);
      return global;
    default: return 0.0;
  }
}
