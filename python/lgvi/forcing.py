"""Forcing written in Python: forces and torques that no potential gives (control laws, damping,
thrust), for ``lgvi.simulate`` and ``lgvi.Stepper``.

The built-in kinds (constant or tabulated torque and force, damping, a PD attitude controller,
sampled or continuous) are ``[[forcing]]`` tables of the scenario file and run at C++ speed; a
PythonForcing adds to them. Both are discretized the same way (docs/guide/forcing.md):
half of the impulse at each end of a step, the end-of-step half at the new state, the momenta
iterated to a fixed point when the forcing reads them.
"""

__all__ = ["PythonForcing"]


class PythonForcing:
    """A forcing ``function(t, x, q, p, w) -> (force, torque)``.

    It receives the time t and one body's state: x the centre of mass (inertial), q the attitude
    scalar-first (w, x, y, z), p the linear momentum, w = 2 J Omega (the body angular momentum is
    w / 2, Omega = J^-1 w / 2), all read-only numpy arrays (3,) or (4,). It returns

    * force: the force at the centre of mass, **inertial frame**, shape (3,);
    * torque: the torque about the centre of mass, **body frame**, shape (3,)
      (an inertial torque tau is R^T tau: ``lgvi.Stepper.rotation_matrix.T @ tau``).

    ``body``: the name of the one body it acts on (default: every body, called once per body).
    ``velocity_dependent``: set False if the function ignores p and w: the end of each step
    then skips the fixed-point iteration of the momenta (one call per step instead of 2-4).

    The run's energy error becomes E - E0 - W with W the work done by all forcing (the row's last
    column, ``work``). The GIL is held while a Python forcing runs.
    """

    def __init__(self, function, *, body=None, velocity_dependent=True):
        if not callable(function):
            raise ValueError(f"function: must be callable as function(t, x, q, p, w), got {function!r}")
        if body is not None and not isinstance(body, str):
            raise ValueError(f"body: must be a body's name (a string) or None, got {body!r}")
        self.function = function
        self.body = body
        self.velocity_dependent = bool(velocity_dependent)

    def __repr__(self):
        return f"PythonForcing({self.function!r}, body={self.body!r}, velocity_dependent={self.velocity_dependent})"


def core_forcing(forcing):
    """The (function, body, velocity_dependent) tuple lgvi._core takes, or None."""
    if forcing is None:
        return None
    if not isinstance(forcing, PythonForcing):
        forcing = PythonForcing(forcing)
    return (forcing.function, forcing.body, forcing.velocity_dependent)
