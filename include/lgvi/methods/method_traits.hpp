// What a method declares about itself. Every N-body stepper class carries
//   static constexpr MethodTraits traits{...};
// in the file that implements it; the application's method registry
// (src/app/method_registry.hpp) lists the classes, and the scenario reader's
// checks, `lgvi compare`, the command line's lists and the Python module's
// METHODS read these declarations instead of naming methods one by one.
#pragma once

namespace lgvi {

struct MethodTraits {
  const char* name;           ///< the scenario's `[integrator] method`
  const char* summary;        ///< one line: what the method is, with its source
  int order;                  ///< global order of accuracy; 0 for an exact flow
  bool symmetric;             ///< the step's adjoint is itself: Phi_{-h} = Phi_h^{-1}
  bool two_step;              ///< a position-position method (carries the previous step)
  bool implicit;              ///< solves an equation per step (SolverOptions apply)
  bool accepts_forcing;       ///< discretizes [[forcing]] (set_forcing)
  bool needs_principal_axes;  ///< every body's inertia must be diagonal in its body axes
  bool free_body_only;        ///< one body, no potential, no interaction (an exact flow)
  /// Takes linear bodies and points (a zero principal moment, rigid_body.hpp).
  bool linear_bodies;

  /// Whether a symmetric composition (composition.hpp) raises the method to
  /// order 4, 6 or 8: symmetric one-step methods of order 2 only.
  constexpr bool composable() const { return symmetric && !two_step && order == 2; }
};

}  // namespace lgvi
