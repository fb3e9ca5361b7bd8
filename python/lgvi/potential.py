"""Potentials V(x, q) for lgvi scenarios and runs.

Built in (compiled, as in scenario files; pass them as ``Scenario(potential=...)``):

* ``none()``: the free body, V = 0;
* ``central(mu)``: central gravity V = -mu sum_i m_i / |x + R rho_i| over the
  body's balls (a body without balls is a point mass);
* ``uniform(g)``: uniform gravity V = -m g . x.

They are plain dicts, ``{"kind": "central", "mu": 1.0}``, the [potential]
table of a scenario file; ``Scenario(potential=...)`` also takes such a dict
or the string ``"none"``.

Written in Python: ``PythonPotential`` (pass it as ``lgvi.simulate(scenario,
potential=...)`` or ``lgvi.Stepper(scenario, potential=...)``).
"""

from . import _check

__all__ = ["none", "central", "uniform", "heavy_top", "PythonPotential", "KINDS"]

#: The built-in potentials' kinds.
KINDS = ("none", "central", "uniform", "heavy-top")


def none():
    """The free body: V = 0. Returns ``{"kind": "none"}``."""
    return {"kind": "none"}


def central(mu, stop_at_contact=False):
    """Central gravity of a point source of strength mu > 0 at the origin.

    V = -mu sum_i m_i / |x + R rho_i| over the body's balls (rho_i relative
    to the centre of mass, R = pi(q)); a body without balls is a point mass.
    With ``stop_at_contact`` the run stops when a ball's centre comes within
    its radius of the source (by default the balls interact as point masses).
    Returns ``{"kind": "central", "mu": mu}`` (plus ``stop_at_contact`` when
    true). ValueError naming ``mu`` unless it is a finite number > 0.
    """
    out = {"kind": "central", "mu": _check.positive(mu, "mu")}
    if stop_at_contact:
        out["stop_at_contact"] = True
    return out


def heavy_top(g, pivot_to_com):
    """A heavy top: the body turns about a fixed pivot (keep x = p = 0) in uniform gravity g.

    V = -m g . (R chi) with chi = ``pivot_to_com`` (3,) in body axes; the body's
    inertia must be given about the pivot. Returns ``{"kind": "heavy-top", "g":
    [...], "pivot_to_com": [...]}``. ValueError naming ``g`` or
    ``pivot_to_com`` unless each is 3 finite numbers.
    """
    return {"kind": "heavy-top", "g": [float(v) for v in _check.vector3(g, "g")],
            "pivot_to_com": [float(v) for v in _check.vector3(pivot_to_com, "pivot_to_com")]}


def uniform(g):
    """Uniform gravity V = -m g . x with acceleration g (3,), e.g. (0, 0, -9.81); no torque.

    Returns ``{"kind": "uniform", "g": [gx, gy, gz]}``. ValueError naming
    ``g`` unless it is 3 finite numbers.
    """
    return {"kind": "uniform", "g": [float(v) for v in _check.vector3(g, "g")]}


def spec(potential, name="potential"):
    """A built-in potential's [potential] table from None, "none", or a dict
    {"kind": ..., "mu" or "g": ...}; ValueError naming the argument otherwise."""
    if potential is None or (isinstance(potential, str) and potential == "none"):
        return none()
    if isinstance(potential, PythonPotential) or callable(potential):
        raise ValueError(f"{name}: a potential written in Python cannot be part of a scenario (a scenario is what "
                         f"a TOML file can say); pass it to lgvi.simulate(scenario, potential=...) or "
                         f"lgvi.Stepper(scenario, potential=...)")
    if not isinstance(potential, dict):
        raise ValueError(f"{name}: must be lgvi.potential.none(), central(mu), uniform(g), a dict like "
                         f"{{'kind': 'central', 'mu': 1.0}} or \"none\"; got {potential!r}")
    kind = _check.choice(potential.get("kind"), f"{name}.kind", KINDS)
    allowed = {"none": set(), "central": {"mu", "stop_at_contact"}, "uniform": {"g"},
               "heavy-top": {"g", "pivot_to_com"}}[kind]
    extra = set(potential) - {"kind"} - allowed
    if extra:
        raise ValueError(f"{name}: unknown key(s) {', '.join(sorted(map(str, extra)))} for kind \"{kind}\"")
    if kind == "central":
        if "mu" not in potential:
            raise ValueError(f"{name}.mu: missing (central gravity needs mu > 0)")
        out = {"kind": "central", "mu": _check.positive(potential["mu"], f"{name}.mu")}
        if "stop_at_contact" in potential:
            if not isinstance(potential["stop_at_contact"], bool):
                raise ValueError(f"{name}.stop_at_contact: must be True or False")
            out["stop_at_contact"] = potential["stop_at_contact"]
        return out
    if kind == "heavy-top":
        for key in ("g", "pivot_to_com"):
            if key not in potential:
                raise ValueError(f"{name}.{key}: missing (a heavy top needs g and pivot_to_com)")
        return {"kind": "heavy-top", "g": [float(v) for v in _check.vector3(potential["g"], f"{name}.g")],
                "pivot_to_com": [float(v) for v in _check.vector3(potential["pivot_to_com"],
                                                                   f"{name}.pivot_to_com")]}
    if kind == "uniform":
        if "g" not in potential:
            raise ValueError(f"{name}.g: missing (uniform gravity needs g = [gx, gy, gz])")
        return {"kind": "uniform", "g": [float(v) for v in _check.vector3(potential["g"], f"{name}.g")]}
    return none()


class PythonPotential:
    """A potential V(x, q) written in Python, for ``lgvi.simulate`` and ``lgvi.Stepper``.

    Give either one function ``function(x, q) -> (energy, force, torque)``
    or three, ``energy(x, q) -> float``, ``force(x, q) -> (3,)``,
    ``torque(x, q) -> (3,)``. They receive x, the centre of mass (numpy
    array (3,), inertial frame), and q, the attitude as a unit quaternion
    **scalar-first (w, x, y, z)** (numpy array (4,)); both arrays are
    read-only. They return

    * energy: V(x, q);
    * force: -dV/dx, the total force in the inertial frame, shape (3,);
    * torque: the body-frame torque M about the centre of mass, shape (3,)
      (for forces f_i at points x + R rho_i: M = sum_i rho_i x (R^T f_i);
      the paper's F(q) dV/dq is -2 M).

    ``check(x, q)`` compares force and torque with finite differences of
    the energy: use it once, a wrong sign of the torque is the usual mistake.

    Cost: the integrator evaluates the potential once per step (plus once at
    the start), with the GIL held; each evaluation makes two small numpy
    arrays and calls Python. Measured on the paper's orbit (2-core Xeon
    2.1 GHz, benchmarks/bench_python.py): the built-in central gravity step
    takes 0.18 us; with a constant Python potential 0.64 us (the call
    overhead, ~0.45 us, the same with one function or three); what the
    Python code itself costs dominates: central gravity of 3 balls written
    with plain Python floats 17 us per step (~100x the built-in), with numpy
    48 us (~270x; each numpy call on a 3-vector costs ~1 us). With three
    functions, work they share (the rotation matrix) is done three times.

    For control loops, the functions may read parameters that change
    between steps (a closure, an attribute): after changing them call
    ``Stepper.refresh()`` so the next step starts from forces evaluated with
    the new parameters (or use ``Stepper.set_potential``).
    """

    def __init__(self, function=None, *, energy=None, force=None, torque=None):
        split = (energy, force, torque)
        if function is not None:
            if any(f is not None for f in split):
                raise ValueError("potential: give either function(x, q) -> (energy, force, torque) or "
                                 "energy=, force= and torque=, not both")
            if not callable(function):
                raise ValueError(f"function: must be callable as function(x, q), got {function!r}")
        else:
            for f, n in zip(split, ("energy", "force", "torque")):
                if f is None:
                    raise ValueError(f"{n}: missing; give function(x, q) -> (energy, force, torque) or all "
                                     f"three of energy=, force=, torque=")
                if not callable(f):
                    raise ValueError(f"{n}: must be callable as {n}(x, q), got {f!r}")
        self.function = function
        self.energy = energy
        self.force = force
        self.torque = torque

    def _core_spec(self):
        """What lgvi._core takes: one callable or a tuple of three."""
        return self.function if self.function is not None else (self.energy, self.force, self.torque)

    def __call__(self, x, q):
        """(energy, force, torque) at x (3,), q (4,) scalar-first (w, x, y, z)."""
        if self.function is not None:
            return self.function(x, q)
        return self.energy(x, q), self.force(x, q), self.torque(x, q)

    def check(self, position, quaternion):
        """Relative errors of force and torque against 4th-order finite differences of the energy.

        At centre of mass ``position`` (3,) and attitude ``quaternion`` (4,),
        scalar-first (w, x, y, z). Returns ``{"force_error": ..,
        "torque_error": ..}``, each |exact - finite difference| / max norm;
        values around 1e-10 or below mean the derivatives are right (the
        C++ test suite's check_potential_derivatives).
        """
        from . import _core
        x = _check.vector3(position, "position")
        q = _check.quaternion(quaternion, "quaternion")
        force_error, torque_error = _core.check_potential(self._core_spec(), x, q)
        return {"force_error": force_error, "torque_error": torque_error}

    def __repr__(self):
        if self.function is not None:
            return f"PythonPotential({getattr(self.function, '__name__', self.function)!s})"
        return "PythonPotential(energy={}, force={}, torque={})".format(
            *(getattr(f, "__name__", f) for f in (self.energy, self.force, self.torque)))


def core_potential(potential, name="potential"):
    """The lgvi._core form of simulate()'s/Stepper's `potential` argument:
    None (the scenario's own), a PythonPotential or a callable (x, q) ->
    (energy, force, torque). Built-in potentials belong in the Scenario."""
    if potential is None:
        return None
    if isinstance(potential, PythonPotential):
        return potential._core_spec()
    if isinstance(potential, (dict, str)):
        raise ValueError(f"{name}: a built-in potential is part of the scenario: use "
                         f"scenario.replace(potential={potential!r}); here give None, a PythonPotential or a "
                         f"callable (x, q) -> (energy, force, torque)")
    if callable(potential):
        return potential
    raise ValueError(f"{name}: must be None (the scenario's own), an lgvi.PythonPotential or a callable "
                     f"(x, q) -> (energy, force, torque); got {potential!r}")
