// LAMMPS data files in ([import] lammps_data): each molecule of the file one
// rigid body, as `fix rigid/small molecule` makes it at set-up.
//
// A molecule's atoms are point masses (or balls, with a radius per atom type)
// at their unwrapped positions x_i + n_i L (n_i the image flags). The body's
// centre of mass X = sum m_i x_i / M, its inertia J = sum m_i (|r_i|^2 I -
// r_i r_i^T) about X (r_i = x_i - X), and its body axes the principal axes of
// J, as LAMMPS takes them: R the eigenvectors (right-handed), the attitude q
// with pi(q) = R, the balls at R^T r_i. The velocities are projected onto
// rigid motion as LAMMPS does: p = sum m_i v_i, and the angular momentum
// L = sum m_i r_i x v_i, so that the body's state has w = 2 R^T L (the paper's
// body momentum doubled; a linear molecule's has no part along its axis).
// Atoms with molecule ID 0 are bodies of one atom each.
#pragma once

#include <lgvi/rigid_body.hpp>
#include <lgvi/state.hpp>

#include "io/trajectory_sink.hpp"

#include <array>
#include <cstdint>
#include <string>
#include <vector>

namespace lgvi::app {

// The application is built on the I/O layer (src/io, namespace lgvi::io, below it:
// io names nothing of app, tests/check_library_layers.py) and names its types unqualified.
using namespace lgvi::io;

/// The bodies of a LAMMPS data file: one per molecule, in increasing
/// molecule ID, then one per atom of molecule ID 0, in increasing atom ID.
/// Identical molecules share a kind (as the bodies of a [[bodies]] block do):
/// body a is kinds[kind[a]], in its principal axes.
struct LammpsDataBodies {
  std::vector<RigidBody> kinds;
  std::vector<std::uint32_t> kind;  ///< per body
  std::vector<std::string> names;  ///< "mol<ID>" or, for molecule ID 0, "atom<ID>"
  std::vector<RigidBodyState> states;
  /// The file's IDs: per body its molecule ID (0 for a body made of an atom
  /// of molecule 0), per site (the bodies' balls in order) its atom ID.
  FileIds ids;
  Vector3<double> lower = Vector3<double>::Zero(), upper = Vector3<double>::Zero();  ///< xlo ylo zlo, xhi yhi zhi
  std::int64_t atoms = 0;
  int atom_types = 0;
  std::string atom_style;  ///< "full" or "molecular" (also bond, angle)
  std::string checksum;    ///< file_checksum of the bytes read (the whole file)
};

/// Reads a data file (atom_style full, molecular, bond or angle: the Atoms
/// lines carry molecule IDs; the style comes from the section's "# style"
/// comment or from `atom_style`, which must agree where both are given).
/// `radius`: empty (point masses), one radius for every atom type, or one per
/// type; `periodic`: the axes with images (a non-zero image flag along an
/// open axis is refused). Throws InvalidInput "FILE:LINE: problem" (or "FILE:
/// problem") for a file that cannot be read as such (a header line or a
/// section name read_data does not know included). Point-mass molecules on
/// one line are linear bodies, single atoms point bodies (rigid_body.hpp), as
/// in LAMMPS; only the methods that take them run them.
LammpsDataBodies read_lammps_data(const std::string& path, const std::vector<double>& radius,
                                  const std::array<bool, 3>& periodic, const std::string& atom_style = "");

/// FNV-1a, 64 bits, of a file's bytes, as 16 hexadecimal digits: the run's
/// copy of the scenario records it, so that a resume from a changed data
/// file is refused rather than run with other bodies. read_lammps_data gives
/// it of the bytes it parsed (LammpsDataBodies::checksum), reading the file once.
std::string file_checksum(const std::string& path);

}  // namespace lgvi::app
