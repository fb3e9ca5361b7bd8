"""Potentials V(x, q) for lgvi scenarios and runs.

Built in (compiled, as in scenario files; pass them as ``Scenario(potential=...)``):

* ``none()``: the free body, V = 0;
* ``central(mu)``: central gravity V = -mu sum_i m_i / |x + R rho_i| over the
  body's balls (a body given by mass and inertia: its second-order potential,
  with the gravity-gradient torque), optionally oblate (``j2``,
  ``reference_radius``, ``pole``);
* ``uniform(g)``: uniform gravity V = -m g . x.

They are plain dicts, ``{"kind": "central", "mu": 1.0}``, the [potential]
table of a scenario file; ``Scenario(potential=...)`` also takes such a dict
or the string ``"none"``.

Written in Python: ``PythonPotential`` (pass it as ``lgvi.simulate(scenario,
potential=...)`` or ``lgvi.Stepper(scenario, potential=...)``).
"""

import numpy as np

from . import _check

__all__ = ["none", "central", "uniform", "heavy_top", "PythonPotential", "KINDS", "CENTRAL_MODELS"]

#: The built-in potentials' kinds.
KINDS = ("none", "central", "uniform", "heavy-top")
#: How a central field acts on a body given by mass and inertia (see central()).
CENTRAL_MODELS = ("extended", "point")


def none():
    """The free body: V = 0. Returns ``{"kind": "none"}``."""
    return {"kind": "none"}


def central(mu, stop_at_contact=False, j2=None, reference_radius=None, pole=None, model="extended"):
    """Central gravity of a source of strength mu > 0 at the origin, optionally oblate.

    V = -mu sum_i m_i / |x + R rho_i| over the body's balls (rho_i relative
    to the centre of mass, R = pi(q)); a body given by mass and inertia J
    feels the second-order (MacCullagh) potential V = -mu m / r - (mu / 2 r^3)
    (tr J - 3 u^T J u), u the direction to the body in body axes, whose
    gravity-gradient torque is (3 mu / r^3) u x J u. ``model="point"`` makes
    such a body a point mass at its centre of mass instead (no torque; balls
    are point masses either way).
    With ``j2`` (and its ``reference_radius`` R_e > 0, the source's equatorial
    radius) each ball feels V = -mu m / r [1 - J2 (R_e / r)^2 P2(pole . r/r)]
    about ``pole`` (3,), a unit vector (default z). With ``stop_at_contact``
    the run stops when a ball's centre comes within its radius of the source
    (by default the balls interact as point masses). Returns ``{"kind":
    "central", "mu": mu}`` plus the keys given, the [potential] table of a
    scenario file. ValueError naming the argument unless mu > 0, j2 and
    reference_radius are finite numbers and pole 3 finite numbers; the
    scenario reader checks the rest (reference_radius > 0, pole unit, j2
    given with the other two).
    """
    out = {"kind": "central", "mu": _check.positive(mu, "mu")}
    if stop_at_contact:
        out["stop_at_contact"] = True
    out.update(_oblate_keys(dict(j2=j2, reference_radius=reference_radius, pole=pole), "potential"))
    if _check.choice(model, "model", CENTRAL_MODELS) != "extended":
        out["model"] = model
    return out


def _oblate_keys(given, name):
    """The J2 keys of a central potential that are not None, as TOML values."""
    out = {}
    for key in ("j2", "reference_radius"):
        if given.get(key) is not None:
            out[key] = _check.number(given[key], f"{name}.{key}")
    if given.get("pole") is not None:
        out["pole"] = [float(v) for v in _check.vector3(given["pole"], f"{name}.pole")]
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
    allowed = {"none": set(), "central": {"mu", "stop_at_contact", "j2", "reference_radius", "pole", "model"},
               "uniform": {"g"},
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
        out.update(_oblate_keys(potential, name))
        if "model" in potential:
            out["model"] = _check.choice(potential["model"], f"{name}.model", CENTRAL_MODELS)
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
    the energy and says whether they pass (``passed``) and, when the errors
    show it, the likely mistake (a torque in the inertial frame or with the
    wrong sign are the usual ones); use it once, at a generic attitude.
    The energy must be a number (a float, a numpy scalar or a 0-d array; an
    array of shape (1,) is refused). A non-finite energy, force or torque
    during a run fails that step, naming it, its time and which was not
    finite.

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

    def check(self, position, quaternion, *, tolerance=1e-6, strict=False):
        """Checks force and torque against 4th-order finite differences of the energy; returns a verdict.

        At centre of mass ``position`` (3,) and attitude ``quaternion`` (4,),
        scalar-first (w, x, y, z). Returns a dict:

        * ``force_error``, ``torque_error``: |returned - finite difference| /
          the larger norm (the C++ ``check_potential_derivatives``; 0 when
          both are 0);
        * ``force_tolerance``, ``torque_tolerance``: what each is held to:
          ``tolerance`` (default 1e-6) plus the round-off floor of the finite
          differences, 100 eps |V| / (h |derivative|) with h = eps^(1/5) (times
          max(1, |x|) for the force): a torque much smaller than |V| (a tidal
          torque) can only be checked that well. The truncation, (h / L)^4
          for a potential varying on a length L, is below 1e-6 for
          L > 0.03 max(1, |x|): a right potential gives errors ~1e-10, a wrong
          one O(1);
        * ``passed``: both errors within their tolerances;
        * ``likely_mistake``: "" or what the error pattern shows: the torque
          in the inertial frame (it equals R times the right body torque),
          the torque or force with the wrong sign (-1 times the right one),
          the torque off by a factor 2 (the paper's F(q) dV/dq is -2 M), the
          force in the body frame.

        ``strict=True`` raises ValueError (with the errors and the likely
        mistake) unless it passed.
        """
        from . import _core
        x = _check.vector3(position, "position")
        q = _check.quaternion(quaternion, "quaternion")
        tol = _check.positive(tolerance, "tolerance")
        force_error, torque_error = _core.check_potential(self._core_spec(), x, q)
        energy, force, torque, force_fd, torque_fd = self._finite_differences(x, q)
        eps = np.finfo(float).eps
        h = eps ** 0.2
        floor_f = 100 * eps * abs(energy) / (h * max(1.0, np.linalg.norm(x)))
        floor_m = 100 * eps * abs(energy) / h

        def limit(floor, a, b):
            scale = max(np.linalg.norm(a), np.linalg.norm(b))
            return tol + (floor / scale if scale > 0 else 0.0)
        force_tol, torque_tol = limit(floor_f, force, force_fd), limit(floor_m, torque, torque_fd)
        passed = bool(force_error <= force_tol and torque_error <= torque_tol)
        mistakes = []
        if not passed:
            R = _rotation(q)

            def close(a, b, t):
                scale = max(np.linalg.norm(a), np.linalg.norm(b))
                return scale > 0 and np.linalg.norm(a - b) <= t * scale
            if torque_error > torque_tol:
                for candidate, text in ((-torque_fd, "the torque has the wrong sign (it should be -dV/dtheta)"),
                                        (R @ torque_fd, "the torque is in the inertial frame: return the body-frame "
                                                        "torque R^T M"),
                                        (-(R @ torque_fd), "the torque is in the inertial frame and has the wrong "
                                                           "sign: return -R^T M"),
                                        (2 * torque_fd, "the torque is twice the right one (F(q) dV/dq = -2 M)"),
                                        (torque_fd / 2, "the torque is half the right one (F(q) dV/dq = -2 M)")):
                    if close(torque, candidate, max(torque_tol, 1e-3)):
                        mistakes.append(text)
                        break
            if force_error > force_tol:
                for candidate, text in ((-force_fd, "the force has the wrong sign (it should be -dV/dx)"),
                                        (R.T @ force_fd, "the force is in the body frame: return the inertial "
                                                         "force R F")):
                    if close(force, candidate, max(force_tol, 1e-3)):
                        mistakes.append(text)
                        break
        out = {"force_error": force_error, "torque_error": torque_error, "force_tolerance": force_tol,
               "torque_tolerance": torque_tol, "passed": passed, "likely_mistake": "; ".join(mistakes)}
        if strict and not passed:
            raise ValueError(f"potential: check failed at position {x.tolist()}, quaternion {q.tolist()}: "
                             f"force error {force_error:.3g} (tolerance {force_tol:.3g}), torque error "
                             f"{torque_error:.3g} (tolerance {torque_tol:.3g})"
                             + (f"; likely: {out['likely_mistake']}" if mistakes else ""))
        return out

    def _finite_differences(self, x, q):
        """(V, force, torque, -dV/dx, -dV/dtheta) at (x, q), the derivatives by the 4th-order central
        differences of the C++ check (h = eps^(1/5), times max(1, |x|) for x; q -> q exp(theta / 2))."""
        def energy(xx, qq):
            return float(np.asarray(self(np.array(xx, dtype=float), np.array(qq, dtype=float))[0], dtype=float))
        e, f, m = self(np.array(x, dtype=float), np.array(q, dtype=float))
        h0 = np.finfo(float).eps ** 0.2

        def diff(g, h):
            return (8.0 * (g(h) - g(-h)) - (g(2 * h) - g(-2 * h))) / (12.0 * h)
        force_fd, torque_fd = np.zeros(3), np.zeros(3)
        for i in range(3):
            unit = np.eye(3)[i]
            force_fd[i] = -diff(lambda t: energy(x + t * unit, q), h0 * max(1.0, np.linalg.norm(x)))
            torque_fd[i] = -diff(lambda t: energy(x, _multiply(q, _exp(t / 2 * unit))), h0)
        return (float(np.asarray(e, dtype=float)), np.asarray(f, dtype=float).reshape(3),
                np.asarray(m, dtype=float).reshape(3), force_fd, torque_fd)

    def __repr__(self):
        if self.function is not None:
            return f"PythonPotential({getattr(self.function, '__name__', self.function)!s})"
        return "PythonPotential(energy={}, force={}, torque={})".format(
            *(getattr(f, "__name__", f) for f in (self.energy, self.force, self.torque)))


def _multiply(a, b):
    """Quaternion product a b, scalar-first."""
    w1, v1, w2, v2 = a[0], np.asarray(a[1:]), b[0], np.asarray(b[1:])
    return np.concatenate([[w1 * w2 - v1 @ v2], w1 * v2 + w2 * v1 + np.cross(v1, v2)])


def _exp(v):
    """exp of the pure quaternion (0, v): (cos|v|, sin|v| v / |v|)."""
    n = np.linalg.norm(v)
    return np.concatenate([[np.cos(n)], (np.sin(n) / n if n > 0 else 1.0) * np.asarray(v)])


def _rotation(q):
    """R = pi(q) (body to inertial) of a unit quaternion, scalar-first."""
    w, x, y, z = q / np.linalg.norm(q)
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
                     [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
                     [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]])


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
