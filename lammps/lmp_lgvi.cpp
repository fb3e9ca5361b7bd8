// lmp-lgvi: LAMMPS (Debian's liblammps) with fix rigid/nve/lgvi registered,
// for a LAMMPS built without the PLUGIN package. Takes LAMMPS's own command
// line (-in, -var, -log, -screen, ...) and runs the input as `lmp` does.
// Part of lgvi, under the GNU General Public License version 2 (lammps/LICENSE).
#include "fix_rigid_nve_lgvi.h"

#include "input.h"
#include "lammps.h"
#include "modify.h"

#include <mpi.h>

namespace {
LAMMPS_NS::Fix* create_fix_rigid_nve_lgvi(LAMMPS_NS::LAMMPS* lmp, int narg, char** arg) {
  return new LAMMPS_NS::FixRigidNVELgvi(lmp, narg, arg);
}
}  // namespace

int main(int argc, char** argv) {
  MPI_Init(&argc, &argv);
  auto* lmp = new LAMMPS_NS::LAMMPS(argc, argv, MPI_COMM_WORLD);
  // What a style's FixStyle() line does in a LAMMPS build, and the PLUGIN
  // package's `plugin load` at run time: the creator in the fix map, by name.
  (*lmp->modify->fix_map)["rigid/nve/lgvi"] = &create_fix_rigid_nve_lgvi;
  (*lmp->modify->fix_map)["rigid/nve/lgvi/small"] = &create_fix_rigid_nve_lgvi;
  lmp->input->file();
  delete lmp;
  MPI_Finalize();
  return 0;
}
