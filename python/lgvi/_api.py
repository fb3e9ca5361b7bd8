"""The public API on top of the compiled lgvi._core: bodies, scenarios,
simulate() and the stepping object. Quaternions are scalar-first (w, x, y,
z) numpy arrays everywhere."""

import copy
import json
import os
import tomllib

import numpy as np

from . import _check, _core
from . import forcing as _forcing
from . import potential as _potential
from ._result import Result
from ._toml import toml_text as _toml_text

__version__ = _core.__version__

#: Integrator methods (the scenario reader's table): the quaternion LGVI's Hamiltonian side
#: ("lgvi", default) and Lagrangian side, and the methods compared with it.
METHODS = _core.METHODS
#: Solvers of the implicit rotation equation (all find the same root).
SOLVERS = _core.SOLVERS
#: Trajectory formats of the CLI ([output] format).
FORMATS = _core.FORMATS
#: Kinds of mutual interaction between the bodies ([interaction] kind; ``interaction={"kind": ...}``).
INTERACTIONS = _core.INTERACTIONS

IntegrationError = _core.IntegrationError


def _value_error(e):
    """A C++ InvalidInput (already a ValueError) re-raised without the C++ frames."""
    return ValueError(str(e))


def _floats(a):
    return [float(v) for v in np.asarray(a, dtype=float).ravel()]


# ---------------------------------------------------------------------------
# Bodies

# The most site types a scenario may use (max_site_types, src/app/scenario.hpp).
MAX_SITE_TYPES = 256


def _ball(b, i):
    name = f"balls[{i}]"
    site_type = None
    if isinstance(b, dict):
        unknown = set(b) - {"position", "mass", "radius", "type"}
        if unknown:
            raise ValueError(f"{name}: unknown key(s) {', '.join(sorted(map(str, unknown)))}; "
                             f"a ball has position, mass, radius and optionally type")
        if "position" not in b or "mass" not in b or "radius" not in b:
            raise ValueError(f"{name}: needs position, mass and radius (radius 0 for a point mass), as a "
                             f"[[body.ball]] of a scenario file does")
        position, mass, radius, site_type = b["position"], b["mass"], b["radius"], b.get("type")
    elif isinstance(b, (tuple, list)) and len(b) == 2:
        raise ValueError(f"{name}: needs (position, mass, radius) (radius 0 for a point mass), as a "
                         f"[[body.ball]] of a scenario file does; got {b!r}")
    elif isinstance(b, (tuple, list)) and len(b) in (3, 4):
        position, mass, radius = b[:3]
        site_type = b[3] if len(b) == 4 else None
    else:
        raise ValueError(f"{name}: must be (position, mass, radius), (position, mass, radius, type) or a dict with "
                         f"position, mass, radius (and type); got {b!r}")
    out = {"position": _floats(_check.vector3(position, f"{name}.position")),
           "mass": _check.positive(mass, f"{name}.mass"),
           "radius": _check.non_negative(radius, f"{name}.radius")}
    if site_type is not None:
        out["type"] = _check.integer(site_type, f"{name}.type", 1, MAX_SITE_TYPES)
    return out


class Body:
    """A rigid body: mass, standard inertia J, and optionally the uniform balls it is made of.

    ``Body(mass=m, inertia=J)``: mass m > 0 and the standard inertia J
    (3x3, body axes, about the centre of mass; symmetric positive definite,
    principal moments with J1 + J2 >= J3).

    ``Body(balls=[...])`` or ``Body.from_balls([...])``: uniform balls, each
    a tuple ``(position, mass, radius)`` or a dict ``{"position": (3,),
    "mass": m, "radius": r}`` (radius required; 0 for a point mass, as in a scenario file). The
    centre of mass is moved to the body origin; J = sum m_i (|rho_i|^2 I -
    rho_i rho_i^T) + 2/5 m_i r_i^2 I. Central gravity acts on each ball.

    ``Body(mass=m, inertia=J, radius=r)``: the same, within a bounding sphere
    of radius r about the centre of mass (checked for contact as that sphere;
    without it such a body is a point for contact).

    ``Body.sphere(radius, density=..)`` and ``Body.ellipsoid((a, b, c),
    density=..)`` (or ``mass=..`` instead of density): uniform solids, mass
    and inertia computed by the exact formulas (semi-axes along the body
    axes).

    Invalid input raises ValueError naming the argument (``mass``,
    ``inertia``, ``balls[1].radius``, ...).
    """

    def __init__(self, mass=None, inertia=None, balls=None, radius=None):
        if balls is not None:
            if mass is not None or inertia is not None or radius is not None:
                raise ValueError("balls: give either mass and inertia (and radius), or balls, not both")
            if isinstance(balls, (str, bytes, dict)) or not hasattr(balls, "__len__") or len(balls) == 0:
                raise ValueError(f"balls: must be a non-empty list of (position, mass, radius), got {balls!r}")
            spec = {"ball": [_ball(b, i) for i, b in enumerate(balls)]}
            try:
                core = _core.Body.from_balls([(b["position"], b["mass"], b["radius"], b.get("type", 1))
                                              for b in spec["ball"]])
            except ValueError as e:
                raise _value_error(str(e).replace("body.ball[", "balls[")
                                   .replace("body.inertia:", "balls: the inertia of these balls")) from None
        else:
            if mass is None or inertia is None:
                raise ValueError("mass, inertia: give both (or balls=[...])")
            m = _check.positive(mass, "mass")
            J = _check.matrix3(inertia, "inertia")
            spec = {"mass": m, "inertia": [_floats(row) for row in J]}
            try:
                core = _core.Body(m, J)
            except ValueError as e:
                raise _value_error(str(e).replace("body.inertia", "inertia").replace("body.mass", "mass")) from None
            if radius is not None:
                spec["radius"] = _check.positive(radius, "radius")
                core = core.bounded_by(spec["radius"])
        self._spec = spec
        self._core = core

    @classmethod
    def from_balls(cls, balls):
        """A body made of uniform balls: (position, mass, radius) tuples or dicts; see Body."""
        return cls(balls=balls)

    @classmethod
    def sphere(cls, radius, density=None, mass=None):
        """A uniform solid sphere of the radius, with density (mass = density 4/3 pi r^3) or mass: J = 2/5 m r^2 I."""
        r = _check.positive(radius, "radius")
        return cls._shape({"shape": "sphere", "radius": r}, (r, r, r), density, mass,
                          lambda m: _core.Body.sphere(m, r))

    @classmethod
    def ellipsoid(cls, semi_axes, density=None, mass=None):
        """A uniform solid ellipsoid of semi-axes (a, b, c) along the body axes, with density (mass = density
        4/3 pi a b c) or mass: J = m/5 diag(b^2 + c^2, a^2 + c^2, a^2 + b^2)."""
        axes = _floats(_check.vector3(semi_axes, "semi_axes"))
        if min(axes) <= 0:
            raise ValueError(f"semi_axes: must be 3 numbers > 0, got {axes!r}")
        return cls._shape({"shape": "ellipsoid", "semi_axes": axes}, axes, density, mass,
                          lambda m: _core.Body.ellipsoid(m, axes))

    @classmethod
    def _shape(cls, spec, axes, density, mass, make):
        if (density is None) == (mass is None):
            raise ValueError("density, mass: give exactly one of them")
        if density is not None:
            spec["density"] = _check.positive(density, "density")
            m = spec["density"] * _core.ellipsoid_volume(axes)  # as the scenario reader computes it
        else:
            m = spec["mass"] = _check.positive(mass, "mass")
        self = cls.__new__(cls)
        try:
            self._core = make(m)
        except ValueError as e:
            raise _value_error(str(e).replace("body.", "")) from None
        self._spec = spec
        return self

    @classmethod
    def _from_table(cls, table):
        """From a scenario's [body] table (as read by tomllib)."""
        if "ball" in table:
            return cls(balls=[dict(b) for b in table["ball"]])
        if "shape" in table:
            size = table["radius"] if table["shape"] == "sphere" else table["semi_axes"]
            make = cls.sphere if table["shape"] == "sphere" else cls.ellipsoid
            return make(size, density=table.get("density"), mass=table.get("mass"))
        return cls(mass=table["mass"], inertia=table["inertia"], radius=table.get("radius"))

    @property
    def mass(self):
        """Total mass m."""
        return self._core.mass

    @property
    def inertia(self):
        """Standard inertia J, 3x3 ndarray (body axes, about the centre of mass)."""
        return self._core.inertia

    @property
    def inertia_inverse(self):
        """J^-1, 3x3 ndarray; the pseudo-inverse for a linear body, zeros for a point."""
        return self._core.inertia_inverse

    @property
    def rotational_dof(self):
        """Rotational degrees of freedom: 3; 2 for a linear body (point masses on one line: no moment about the
        line, no rotation about it); 0 for a point mass."""
        return self._core.rotational_dof

    @property
    def linear_axis(self):
        """A linear body's axis n (body frame, unit), J = I (1 - n n^T); zeros otherwise."""
        return self._core.linear_axis

    @property
    def balls(self):
        """The balls as dicts {"position": (3,) relative to the centre of mass, "mass", "radius"}; [] if none."""
        return self._core.balls

    @property
    def extent(self):
        """What is known of its extent: "balls", "sphere" (a sphere, or mass + inertia with radius), "ellipsoid",
        or "point" (mass + inertia only: contact tests treat it as its centre of mass)."""
        return self._core.extent

    @property
    def semi_axes(self):
        """(a, b, c) of an ellipsoid, (r, r, r) of a sphere or bounding sphere; zeros otherwise."""
        return self._core.semi_axes

    def __repr__(self):
        if "ball" in self._spec:
            return f"lgvi.Body(balls={len(self._spec['ball'])} balls, mass={self.mass!r})"
        if "shape" in self._spec:
            size = {k: self._spec[k] for k in ("radius", "semi_axes") if k in self._spec}
            return f"lgvi.Body.{self._spec['shape']}(**{size!r}, mass={self.mass!r})"
        return f"lgvi.Body(mass={self.mass!r}, inertia={self.inertia.tolist()!r})"


# ---------------------------------------------------------------------------
# Scenarios

_INITIAL_PAIRS = (("momentum", "velocity"), ("w", "omega"))
_INTEGRATOR_KEYS = ("method", "solver", "step", "duration", "tolerance", "max_iterations", "predictor_order",
                    "order", "composition")
# The adaptive step's keys ([integrator] time_transform = "potential"; docs/guide/adaptive-step.md).
_ADAPTIVE_KEYS = ("time_transform", "epsilon", "monitor_scale", "max_steps", "exact_finish")


def _apply_adaptive(integ, changes):
    """time_transform, epsilon, monitor_scale, max_steps and exact_finish (keyword arguments) into the
    [integrator] dict `integ`: "potential" replaces step by epsilon, "none" or None drops the five; None drops one. The reader
    checks the rest (what the adaptive step does not take)."""
    if "time_transform" in changes:
        kind = changes["time_transform"]
        if kind is None or _check.choice(kind, "time_transform", ("none", "potential")) == "none":
            for key in _ADAPTIVE_KEYS:
                integ.pop(key, None)
        else:
            if changes.get("step") is not None:
                raise ValueError('step: with time_transform="potential" the physical step adapts; give epsilon, '
                                 "the fictitious-time step, instead")
            integ["time_transform"] = "potential"
            integ.pop("step", None)
    for key, check in (("epsilon", lambda v: _check.positive(v, "epsilon")),
                       ("monitor_scale", lambda v: _check.positive(v, "monitor_scale")),
                       ("max_steps", lambda v: _check.integer(v, "max_steps", 1)),
                       ("exact_finish", lambda v: _check.boolean(v, "exact_finish"))):
        if key in changes:
            if changes[key] is None:
                integ.pop(key, None)
            else:
                integ[key] = check(changes[key])


def _composition(value):
    """[gamma_1, ..., gamma_s]: a sequence of finite numbers (the reader checks sum and symmetry)."""
    if isinstance(value, (str, bytes)) or not hasattr(value, "__iter__"):
        raise ValueError(f"composition: must be a sequence of numbers [gamma_1, ..., gamma_s], got {value!r}")
    return [_check.number(g, f"composition[{i}]") for i, g in enumerate(value)]


def _apply(doc, changes):
    """Validates `changes` (Scenario keyword arguments) and writes them into the TOML document `doc`."""
    doc.setdefault("initial", {})
    doc.setdefault("integrator", {})
    if "body" in changes:
        body = changes["body"]
        if isinstance(body, dict):
            body = Body(**body)
        if not isinstance(body, Body):
            raise ValueError(f"body: must be an lgvi.Body, got {body!r}")
        doc["body"] = copy.deepcopy(body._spec)
    if "potential" in changes:
        doc["potential"] = _potential.spec(changes["potential"])
    init = doc["initial"]
    for key in ("orbit", "attitude"):
        if changes.get(key) is not None:
            if not isinstance(changes[key], dict):
                raise ValueError(f"{key}: must be a dict, e.g. " + (
                    "orbit=dict(altitude=500e3, inclination=51.6)" if key == "orbit"
                    else 'attitude=dict(frame="lvlh", pitch=5.0, rate="orbit")'))
            init[key] = {k: (float(v) if isinstance(v, int) and not isinstance(v, bool) else v)
                         for k, v in changes[key].items()}
    if changes.get("position") is not None:
        init["position"] = _floats(_check.vector3(changes["position"], "position"))
    if changes.get("quaternion") is not None:
        init["quaternion"] = _floats(_check.quaternion(changes["quaternion"], "quaternion"))
    for a, b in _INITIAL_PAIRS:
        if changes.get(a) is not None and changes.get(b) is not None:
            raise ValueError(f"{a}, {b}: give one of them, not both")
        for key, other in ((a, b), (b, a)):
            if changes.get(key) is not None:
                init[key] = _floats(_check.vector3(changes[key], key))
                init.pop(other, None)
    integ = doc["integrator"]
    if "method" in changes:
        integ["method"] = _check.choice(changes["method"], "method", METHODS)
    if "solver" in changes:
        integ["solver"] = _check.choice(changes["solver"], "solver", SOLVERS)
    if changes.get("step") is not None:
        integ["step"] = _check.positive(changes["step"], "step")
    _apply_adaptive(integ, changes)
    if "duration" in changes:
        integ["duration"] = _check.non_negative(changes["duration"], "duration")
    for key, check in (("tolerance", lambda v: _check.positive(v, "tolerance")),
                       ("max_iterations", lambda v: _check.integer(v, "max_iterations", 1, 10000)),
                       ("predictor_order", lambda v: _check.integer(v, "predictor_order", 0, 3))):
        if key in changes:
            if changes[key] is None:
                integ.pop(key, None)
            else:
                integ[key] = check(changes[key])
    # order and composition exclude each other: setting one drops the other
    # (the reader checks the values and the method).
    for key, other, check in (("order", "composition", lambda v: _check.integer(v, "order", 2, 8)),
                              ("composition", "order", _composition)):
        if key in changes:
            if changes[key] is None:
                integ.pop(key, None)
            else:
                integ[key] = check(changes[key])
                integ.pop(other, None)
    if "every" in changes or "output_format" in changes:
        out = doc.setdefault("output", {})
        if "every" in changes:
            out["every"] = _check.integer(changes["every"], "every", 1)
        if "output_format" in changes:
            out["format"] = _check.choice(changes["output_format"], "output_format", FORMATS)
    return doc


class Scenario:
    """One run: body, potential, initial state, integrator and output, as in a scenario file.

    Build one in code (keyword arguments; quaternion **scalar-first (w, x,
    y, z)**)::

        lgvi.Scenario(body=lgvi.Body(mass=1.0, inertia=np.diag([1.0, 2.0, 3.0])),
                      potential=lgvi.potential.central(1.0),
                      position=(8, 0, 0), quaternion=(1, 0, 0, 0),
                      momentum=(0, 1, 0), w=(1, 2, 3), step=0.01, duration=100.0)

    or read one: ``Scenario.from_toml(path)``, ``Scenario.from_string(text)``.

    Arguments: ``body`` (lgvi.Body, required); ``potential``
    (``lgvi.potential.none()`` (default), ``central(mu)``, ``uniform(g)``, a
    dict ``{"kind": ..}`` or "none"); ``position`` x0 (3,);
    ``quaternion`` q0 (4,), scalar-first (w, x, y, z), within 1e-6 of unit
    norm (then normalized); ``momentum`` p0 or ``velocity`` v0 = p0 / m
    (3,); ``w`` w0 = 2 J Omega0 (the paper's variable) or ``omega`` Omega0,
    the body angular velocity (3,) (the initial state is required, with no
    defaults, as [initial] of a scenario file requires it); ``orbit`` a dict
    of the scenario key [initial] orbit (``altitude`` | ``radius``,
    ``eccentricity``, ``inclination``, ``raan``, ``arg_periapsis``,
    ``true_anomaly``; degrees; with a central potential) in place of position
    and momentum; ``attitude`` a dict of [initial] attitude
    (``frame="lvlh"``, ``roll``, ``pitch``, ``yaw`` in degrees,
    ``rate="orbit"``) in place of quaternion (and, with rate, of w);
    converted by the reader, so ``scenario.toml`` holds the plain keys;
    ``step`` h > 0 and ``duration`` >= 0 (required; the
    run takes ceil(duration / step) steps); or, for the adaptive LGVI under
    gravity (docs/guide/adaptive-step.md), ``time_transform="potential"``
    with ``epsilon`` (the fictitious-time step, in place of step),
    ``monitor_scale`` (c; None: |V| at the start), ``max_steps`` (None:
    100 duration / epsilon) and ``exact_finish``: the run ends with the first
    step that reaches the duration (with exact_finish=True, shortened to end
    there exactly); ``method`` one of lgvi.METHODS
    ("lgvi", the Hamiltonian side, is the default; "lgvi-lagrangian",
    "so3-lgvi", "rattle-quaternion", "rk4-normalized", "euler-exp",
    "no-squish", "splitting-dlm", "exact"); ``solver`` "newton" (default),
    "newton-exp" or "broyden"; ``tolerance``, ``max_iterations``,
    ``predictor_order`` (solver options; None = the default); ``order`` 2,
    4, 6 or 8 or ``composition`` [gamma_1, ..., gamma_s] (the method composed
    to higher order; symmetric one-step methods only; None = order 2);
    ``every`` (a
    trajectory row every this many steps, plus the first and last; default
    1); ``output_format`` for the CLI ("csv", "npz", "hdf5", or the viewer
    exports "xyz" for OVITO, "vtk" for ParaView and "lammps-dump" for
    LAMMPS's tools, OVITO and VMD); ``name``.

    The scenario is written as TOML (``.toml``) and read by the CLI's own
    reader, so a code-built scenario is validated exactly like a file and
    ``lgvi run`` on ``scenario.save(path)`` gives the same run. Invalid
    arguments raise ValueError naming the argument.
    """

    def __init__(self, *, body, step=None, duration, potential=None, position=None,
                 quaternion=None, momentum=None, velocity=None, w=None, omega=None,
                 method="lgvi", solver="newton", tolerance=None, max_iterations=None, predictor_order=None,
                 order=None, composition=None, every=1, output_format="csv", name="scenario",
                 orbit=None, attitude=None, time_transform=None, epsilon=None, monitor_scale=None, max_steps=None,
                 exact_finish=None):
        changes = dict(body=body, potential=potential, position=position, quaternion=quaternion,
                       momentum=momentum, velocity=velocity, w=w, omega=omega, method=method, solver=solver,
                       step=step, duration=duration, tolerance=tolerance, max_iterations=max_iterations,
                       predictor_order=predictor_order, every=every, orbit=orbit, attitude=attitude)
        _require_step(step, time_transform, changes, epsilon=epsilon, monitor_scale=monitor_scale,
                      max_steps=max_steps, exact_finish=exact_finish)
        if order is not None:
            changes["order"] = order
        if composition is not None:
            changes["composition"] = composition
        if output_format != "csv":
            changes["output_format"] = output_format
        # The initial state is required, as [initial] of a scenario file
        # requires it: no silent zeros. orbit gives position and momentum,
        # attitude the quaternion (and, with rate = "orbit", w).
        rate_given = isinstance(attitude, dict) and "rate" in attitude
        for key, value, alternative, text in (
                ("position", position, orbit, "x0 (3,) or orbit"),
                ("quaternion", quaternion, attitude, "q0 (4,), scalar-first, (1, 0, 0, 0) for no rotation, or attitude")):
            if value is None and alternative is None:
                raise ValueError(f"{key}: missing: give {text}, as [initial] of a scenario file requires")
        if momentum is None and velocity is None and orbit is None:
            raise ValueError("momentum, velocity: give one of them ((0, 0, 0) for a body at rest) or orbit, as "
                             "[initial] of a scenario file requires")
        if w is None and omega is None and not rate_given:
            raise ValueError("w, omega: give one of them ((0, 0, 0) for no rotation) or attitude with rate, as "
                             "[initial] of a scenario file requires")
        doc = _apply({}, changes)
        self._init(_parse(_toml_text(doc), _check_name(name)), doc)

    def _init(self, core, doc=None):
        self._core = core
        self._doc = doc

    @classmethod
    def _wrap(cls, core):
        self = cls.__new__(cls)
        self._init(core)
        return self

    @classmethod
    def from_toml(cls, path):
        """Read a scenario file exactly as ``lgvi run`` does (its name is the file's stem).

        FileNotFoundError if there is no such file; ValueError with the CLI's
        message ("FILE: key 'integrator.step': must be > 0, ...") if it is invalid.
        """
        path = os.fspath(path)
        if not os.path.exists(path):
            raise FileNotFoundError(2, "No such scenario file", path)
        try:
            return cls._wrap(_core.read_scenario(path))
        except ValueError as e:
            raise _value_error(e) from None

    @classmethod
    def from_string(cls, text, name="scenario", directory=None):
        """Parse scenario TOML text exactly as ``lgvi run`` reads a file; ValueError with the CLI's message.

        The files the text names by relative paths (``[import] lammps_data``, forcing tables) are
        read from ``directory``, as a scenario file's are from its folder; None: from the folder in
        ``name``, if it has one, else the current directory.
        """
        if not isinstance(text, str):
            raise ValueError(f"text: must be a str of TOML, got {type(text).__name__}")
        name = _check_name(name)
        if directory is not None:
            if (not isinstance(directory, (str, os.PathLike)) or not isinstance(os.fspath(directory), str)
                    or not os.path.isdir(directory)):
                raise ValueError(f"directory: must be an existing folder, got {directory!r}")
            if os.path.isabs(name):
                raise ValueError(f"name: {name!r} is an absolute path; with directory, give the name alone")
            name = os.path.join(os.fspath(directory), name)
        return cls._wrap(_parse(text, name))

    @classmethod
    def from_arrays(cls, *, bodies, positions, quaternions, step=None, duration, momenta=None, velocities=None,
                    w=None, omegas=None, names=None, potential=None, interaction=None, method="lgvi", order=None,
                    every=1, threads=None, on_contact=None, box=None, name="scenario", time_transform=None,
                    epsilon=None, monitor_scale=None, max_steps=None, exact_finish=None):
        """A scenario of N bodies from numpy arrays (a ``[[bodies]]`` scenario file, written and read).

        ``bodies``: one lgvi.Body for every row, or a list of N of them;
        ``positions`` (N, 3); ``quaternions`` (N, 4) scalar-first, each within
        1e-6 of unit norm (then normalized); ``momenta`` or ``velocities``
        (N, 3); ``w`` (N, 3, the paper's w = 2 J Omega) or ``omegas`` (N, 3,
        body angular velocities); ``names`` (N unique names; default body0,
        body1, ...); ``potential`` the external field on every body (as for
        Scenario); ``interaction`` None or a dict ``{"kind": "gravity", "G":
        1.0, "model": "balls" | "inertia"}`` or ``{"kind": "lennard-jones",
        "epsilon": .., "sigma": .., "cutoff": .., "skin": ..}``; ``method``,
        ``order``, ``step``, ``duration``, ``every`` and the adaptive step's
        ``time_transform``, ``epsilon``, ``monitor_scale``, ``max_steps``, ``exact_finish`` as for Scenario;
        ``threads`` for the per-body loops (default: all cores);
        ``on_contact`` ([run] on_contact): "stop" (the default; lgvi.simulate
        then raises lgvi.IntegrationError at the first step where two bodies
        overlap, its ``result`` the run up to that step), "warn" (contact
        episodes in ``summary["contacts"]``) or "ignore" (the default of
        Lennard-Jones systems); ``box`` ([box]) None (free space) or a dict
        ``{"lower": (3,), "upper": (3,), "periodic": (3,) of bool}`` (periodic
        default all true): pairs interact through their minimum image, and the
        positions stay unwrapped in the results.

        Validated by the reader of ``lgvi run`` (overlapping bodies, duplicate
        names, ...): ValueError naming the argument or the scenario key
        (``bodies[3]`` is row 3).
        """
        return _from_arrays(cls, bodies=bodies, positions=positions, quaternions=quaternions, step=step,
                            duration=duration, momenta=momenta, velocities=velocities, w=w, omegas=omegas,
                            names=names, potential=potential, interaction=interaction, method=method, order=order,
                            every=every, threads=threads, on_contact=on_contact, box=box, name=name,
                            time_transform=time_transform, epsilon=epsilon, monitor_scale=monitor_scale,
                            max_steps=max_steps, exact_finish=exact_finish)

    @classmethod
    def from_lammps_data(cls, path, *, interaction, step, duration, radius=None, periodic=None, atom_style=None,
                         potential=None, method="lgvi", order=None, every=1, threads=None, on_contact=None,
                         name=None):
        """A scenario of the molecules of a LAMMPS data file (``[import] lammps_data``), each one rigid body.

        ``path``: the data file (atom_style full, molecular, bond or angle:
        Atoms with molecule IDs, Masses, optional Velocities; the box from
        its bounds). Each molecule's atoms are point masses (or balls of
        ``radius``: one number, or one per atom type) at their unwrapped
        positions; its momentum and angular momentum are the rigid projection
        of the atoms' velocities, as LAMMPS's ``fix rigid/small`` makes them.
        ``periodic``: 3 booleans (default all true, ``boundary p p p``).
        ``atom_style``: "full", "molecular", "bond" or "angle", where the
        file's Atoms section does not name it.
        ``interaction``: as for from_arrays, e.g. ``{"kind": "lennard-jones",
        "cutoff": 2.5, "pair": [{"types": (1, 1), "epsilon": 1.0, "sigma":
        1.0}, ...], "mixing": "geometric"}`` (the atom types are the site
        types). ``name``: default the file's stem. The rest as for
        from_arrays. ValueError with the reader's one-line message, naming
        the file and the line, for a file it cannot read.
        """
        path = os.path.abspath(os.fspath(path))
        if not os.path.isfile(path):
            raise FileNotFoundError(2, "No such LAMMPS data file", path)
        table = {"lammps_data": path}
        if radius is not None:
            if isinstance(radius, (list, tuple, np.ndarray)):
                table["radius"] = [_check.non_negative(r, f"radius[{k}]") for k, r in enumerate(radius)]
            else:
                table["radius"] = _check.non_negative(radius, "radius")
        if periodic is not None:
            table["periodic"] = _periodic(periodic, "periodic")
        if atom_style is not None:
            table["atom_style"] = _check.choice(atom_style, "atom_style", ("full", "molecular", "bond", "angle"))
        integ, run = _integrator_and_run(method, step, duration, order, threads, on_contact)
        tables = (("import", table), ("potential", _potential.spec(potential)),
                  ("interaction", _interaction(interaction)), ("integrator", integ),
                  ("output", {"every": _check.integer(every, "every", 1)}), ("run", run or None))
        stem = os.path.splitext(os.path.basename(path))[0]
        text = _toml_text({key: t for key, t in tables if t is not None})
        return cls._wrap(_parse(text, _check_name(stem if name is None else name)))

    def replace(self, **changes):
        """A copy with some arguments changed, e.g. ``scenario.replace(step=0.005, duration=10)``.

        Takes the constructor's keyword arguments (``velocity`` replaces
        ``momentum`` and ``omega`` replaces ``w``, and vice versa). The rest of
        the scenario, balls included, is kept as written.
        """
        unknown = set(changes) - {"body", "potential", "position", "quaternion", "momentum", "velocity", "w",
                                  "omega", "method", "solver", "step", "duration", "tolerance", "max_iterations",
                                  "predictor_order", "order", "composition", "every", "output_format", "name",
                                  *_ADAPTIVE_KEYS}
        if unknown:
            raise ValueError(f"{', '.join(sorted(unknown))}: not a scenario argument")
        if "bodies" in self.document or "import" in self.document:
            raise ValueError("replace: changes single-body scenarios; build a scenario of many bodies anew with "
                             "lgvi.Scenario.from_arrays(...) or edit its TOML (scenario.toml)")
        name = _check_name(changes.pop("name", self.name))
        doc = _apply(copy.deepcopy(self.document), changes)
        return Scenario._wrap(_parse(_toml_text(doc), name))

    @property
    def document(self):
        """The scenario as a dict of TOML tables (body, potential, initial, integrator, output)."""
        if self._doc is None:
            self._doc = tomllib.loads(self._core.toml)
        return self._doc

    @property
    def name(self):
        """The scenario's name (a file's stem; summary["scenario"])."""
        return self._core.name

    @property
    def toml(self):
        """The scenario as TOML text (for a file: its text as read)."""
        return self._core.toml

    @property
    def body(self):
        """The body (lgvi.Body)."""
        return Body._from_table(self.document["body"])

    @property
    def potential(self):
        """The built-in potential as a dict, every key as the scenario gives it: {"kind": "none"},
        {"kind": "central", "mu": .., and j2, reference_radius, pole, stop_at_contact, model where given},
        {"kind": "uniform", "g": [..]} or {"kind": "heavy-top", "g": [..], "pivot_to_com": [..]}.
        ``Scenario(potential=scenario.potential)`` gives the same potential."""
        # From the scenario's own table, so that no key is dropped (an earlier
        # version rebuilt the dict from kind, mu and g alone and lost heavy-top's
        # pivot_to_com, J2 and stop_at_contact).
        table = copy.deepcopy(self.document.get("potential", {}))
        table.setdefault("kind", self._core.potential_kind)
        return table

    @property
    def position(self):
        """Initial centre of mass x0 (3,)."""
        return self._core.position

    @property
    def quaternion(self):
        """Initial attitude q0 (4,), scalar-first (w, x, y, z), normalized."""
        return self._core.quaternion

    @property
    def momentum(self):
        """Initial linear momentum p0 (3,)."""
        return self._core.momentum

    @property
    def velocity(self):
        """Initial velocity p0 / m (3,)."""
        return self._core.momentum / self._core.body.mass

    @property
    def w(self):
        """Initial w0 = 2 J Omega0 (3,), the paper's angular momentum variable."""
        return self._core.w

    @property
    def omega(self):
        """Initial body angular velocity Omega0 = J^-1 w0 / 2 (3,); for a body with reaction wheels, whose w0 holds
        the wheels' momentum too, use lgvi.simulate's Result.omega."""
        if "wheel" in (self.document.get("body") or {}):
            raise ValueError("omega: this body has reaction wheels; its rate is J_s^-1 (w0/2 - h_w) (Result.omega of "
                             "lgvi.simulate gives it)")
        return 0.5 * (self._core.body.inertia_inverse @ self._core.w)

    @property
    def step(self):
        """Step size h (with time_transform="potential": epsilon, the fictitious-time step)."""
        return self._core.step

    @property
    def time_transform(self):
        """"none" (a fixed step) or "potential" (the adaptive LGVI: ``step`` is epsilon, ``steps`` max_steps)."""
        return self.document["integrator"].get("time_transform", "none")

    @property
    def duration(self):
        """Duration as given; the run ends at steps * step."""
        return self._core.duration

    @property
    def steps(self):
        """Number of steps, ceil(duration / step) (forgiving round-off: 1000 / 0.01 is 100000); with
        time_transform="potential", the most it may take (max_steps)."""
        return self._core.steps

    @property
    def method(self):
        """The method's name, one of lgvi.METHODS ("lgvi" is the Hamiltonian side, the default)."""
        return self._core.method

    @property
    def solver(self):
        """"newton", "newton-exp" or "broyden"."""
        return self._core.solver

    @property
    def on_contact(self):
        """What a run does when two bodies overlap, as it applies: "stop", "warn" or "ignore" ([run] on_contact,
        or its default: "stop" for [[bodies]], "ignore" for Lennard-Jones systems and a single body)."""
        return self._core.on_contact

    @property
    def tolerance(self):
        """The solver's relative tolerance (default 4 eps)."""
        return self._core.tolerance

    @property
    def max_iterations(self):
        """The solver's iteration limit."""
        return self._core.max_iterations

    @property
    def predictor_order(self):
        """Degree of the solver's initial-guess extrapolation, 0..3."""
        return self._core.predictor_order

    @property
    def order(self):
        """The order of the composed method: 2 (the method's own step), 4, 6 or 8 (2 for a user's table)."""
        return self._core.order

    @property
    def composition(self):
        """The sub-step fractions gamma_1..gamma_s of a composed step ((1.0,) for the method's own step)."""
        return tuple(self._core.composition)

    @property
    def every(self):
        """A trajectory row every this many steps (plus the first and the last)."""
        return self._core.every

    @property
    def output_format(self):
        """The CLI's trajectory format: "csv", "npz", "hdf5", "xyz" (OVITO), "vtk" (ParaView) or "lammps-dump" (LAMMPS)."""
        return self._core.output_format

    @property
    def layout(self):
        """The trajectory's row layout ([output] layout): "single-body" (one row a written step, one body's
        columns: a [body] scenario's default) or "long" (one row a step and body: [[bodies]]'s default)."""
        return self._core.layout

    def evaluate_potential(self, position, quaternion):
        """The built-in potential at x (3,), q (4,) scalar-first (w, x, y, z): (energy, force (3,), torque (3,))."""
        x = _check.vector3(position, "position")
        q = _check.quaternion(quaternion, "quaternion")
        return self._core.evaluate_potential(x, q)

    def save(self, path):
        """Write the scenario's TOML to `path` (for ``lgvi run``). Returns path."""
        with open(path, "w", encoding="utf-8") as f:
            f.write(self.toml)
        return path

    def __repr__(self):
        return (f"<lgvi.Scenario {self.name!r}: {self.potential['kind']} potential, {self.method}/{self.solver}, "
                f"step {self.step!r}, {self.steps} steps>")


# ---------------------------------------------------------------------------
# Many bodies from arrays

# [interaction] kind -> the keys it takes besides kind: the reader's registry (src/app/interactions/registry.cpp).
_INTERACTION_KEYS = {kind: set(keys) for kind, keys in _core.INTERACTION_KEYS.items()}


def _interaction(interaction):
    """The [interaction] table from None or a dict {"kind": "gravity", "G": ...}; ValueError naming the key."""
    if interaction is None:
        return None
    if not isinstance(interaction, dict):
        raise ValueError(f"interaction: must be a dict like {{'kind': 'gravity', 'G': 1.0}}, got {interaction!r}")
    kind = _check.choice(interaction.get("kind"), "interaction.kind", tuple(_INTERACTION_KEYS))
    extra = set(interaction) - {"kind"} - _INTERACTION_KEYS[kind]
    if extra:
        raise ValueError(f"interaction: unknown key(s) {', '.join(sorted(map(str, extra)))} for kind \"{kind}\"")
    out = {"kind": kind}
    for k, v in interaction.items():
        if k == "model":
            out[k] = _check.choice(v, "interaction.model", ("balls", "inertia"))
        elif k == "mixing":
            out[k] = _check.choice(v, "interaction.mixing", ("geometric", "arithmetic"))
        elif k == "pair":
            out[k] = _type_pairs(v)
        elif k != "kind":
            out[k] = _check.number(v, f"interaction.{k}")
    return out


def _type_pairs(pairs):
    """[[interaction.pair]] from a list of dicts {"types": (i, j), "epsilon": .., "sigma": ..}."""
    if isinstance(pairs, (str, bytes, dict)) or not hasattr(pairs, "__len__") or len(pairs) == 0:
        raise ValueError(f"interaction.pair: must be a non-empty list of dicts {{'types': (1, 2), 'epsilon': .., "
                         f"'sigma': ..}}, got {pairs!r}")
    out = []
    for k, p in enumerate(pairs):
        name = f"interaction.pair[{k}]"
        if not isinstance(p, dict) or set(p) != {"types", "epsilon", "sigma"}:
            raise ValueError(f"{name}: must be a dict with types, epsilon and sigma, got {p!r}")
        types = p["types"]
        if isinstance(types, (str, bytes)) or not hasattr(types, "__len__") or len(types) != 2:
            raise ValueError(f"{name}.types: must be two site types (i, j), got {types!r}")
        out.append({"types": [_check.integer(t, f"{name}.types", 1, MAX_SITE_TYPES) for t in types],
                    "epsilon": _check.positive(p["epsilon"], f"{name}.epsilon"),
                    "sigma": _check.positive(p["sigma"], f"{name}.sigma")})
    return out


def _rows(value, name, n, width):
    """An (n, width) float array from `value`; ValueError naming the argument."""
    try:
        a = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise ValueError(f"{name}: must be an array of shape ({n}, {width}) of numbers, got {value!r}") from None
    if a.shape != (n, width):
        raise ValueError(f"{name}: must have shape ({n}, {width}) (one row per body), got {a.shape}")
    bad = np.argwhere(~np.isfinite(a))
    if len(bad):
        raise ValueError(f"{name}[{bad[0][0]}]: must be finite, got {a[tuple(bad[0])]!r}")
    return a


def _system_toml(bodies, rows, names, potential, interaction, integrator, every, run, box=None):
    """TOML text of a [[bodies]] scenario."""
    tables = []
    for a, body in enumerate(bodies):
        t = {} if names is None else {"name": names[a]}
        t.update((key, _floats(array[a])) for key, array in rows.items())
        t.update(body._spec)  # [[bodies.ball]] tables; or mass + inertia (+ radius), or a shape
        tables.append(t)
    doc = {"bodies": tables}
    for table, t in (("potential", potential), ("interaction", interaction), ("box", box),
                     ("integrator", integrator), ("output", {"every": every}), ("run", run or None)):
        if t is not None:
            doc[table] = t
    return _toml_text(doc)


def _from_arrays(cls, *, bodies, positions, quaternions, step, duration, momenta=None, velocities=None, w=None,
                 omegas=None, names=None, potential=None, interaction=None, method="lgvi", order=None,
                 every=1, threads=None, on_contact=None, box=None, name="scenario", time_transform=None,
                 epsilon=None, monitor_scale=None, max_steps=None, exact_finish=None):
    if isinstance(bodies, dict):
        bodies = Body(**bodies)
    if isinstance(bodies, Body):
        shape = np.shape(positions)
        if len(shape) != 2 or shape[0] == 0:
            raise ValueError(f"positions: must be an (N, 3) array, one row per body, got shape {shape}")
        bodies = [bodies] * shape[0]
    if isinstance(bodies, (str, bytes)) or not hasattr(bodies, "__len__") or len(bodies) == 0:
        raise ValueError(f"bodies: must be an lgvi.Body (the same for every row) or a list of them, got {bodies!r}")
    bodies = [Body(**b) if isinstance(b, dict) else b for b in bodies]
    for a, b in enumerate(bodies):
        if not isinstance(b, Body):
            raise ValueError(f"bodies[{a}]: must be an lgvi.Body, got {b!r}")
    n = len(bodies)
    rows = {"position": _rows(positions, "positions", n, 3)}
    q = _rows(quaternions, "quaternions", n, 4)
    for a in range(n):
        q[a] = _check.quaternion(q[a], f"quaternions[{a}]")
    rows["quaternion"] = q
    for key, (first, second), (k1, k2) in (("momenta", (momenta, velocities), ("momentum", "velocity")),
                                           ("w", (w, omegas), ("w", "omega"))):
        label = ("momenta", "velocities") if key == "momenta" else ("w", "omegas")
        if first is not None and second is not None:
            raise ValueError(f"{label[0]}, {label[1]}: give one of them, not both")
        if first is None and second is None:
            raise ValueError(f"{label[0]}, {label[1]}: give one of them (an (N, 3) array; zeros for rest)")
        if first is not None:
            rows[k1] = _rows(first, label[0], n, 3)
        else:
            rows[k2] = _rows(second, label[1], n, 3)
    if names is not None:
        names = [str(x) for x in names]
        if len(names) != n:
            raise ValueError(f"names: must have one name per body ({n}), got {len(names)}")
    adaptive = {}
    _require_step(step, time_transform, adaptive, epsilon=epsilon, monitor_scale=monitor_scale, max_steps=max_steps,
                  exact_finish=exact_finish)
    integ, run = _integrator_and_run(method, step, duration, order, threads, on_contact, adaptive)
    text = _system_toml(bodies, rows, names, _potential.spec(potential), _interaction(interaction), integ,
                        _check.integer(every, "every", 1), run, _box(box))
    return cls._wrap(_parse(text, _check_name(name)))


def _require_step(step, time_transform, changes, **adaptive):
    """A fixed step needs ``step``; time_transform="potential" needs ``epsilon`` instead. Adds the adaptive
    step's keyword arguments that were given to `changes` (for _apply_adaptive)."""
    if time_transform is not None:
        changes["time_transform"] = time_transform
    changes.update({k: v for k, v in adaptive.items() if v is not None})
    if time_transform == "potential":
        if adaptive.get("epsilon") is None:
            raise ValueError('epsilon: missing: time_transform="potential" takes epsilon, the fictitious-time '
                             "step (e.g. 0.02), in place of step")
    elif step is None:
        raise ValueError('step: missing: give the step h > 0 (or time_transform="potential" with epsilon)')


def _integrator_and_run(method, step, duration, order, threads, on_contact, adaptive=None):
    """The [integrator] and [run] tables of a many-body scenario built in Python; ValueError naming the argument.
    `adaptive`: the adaptive step's keyword arguments (_require_step), if any."""
    integ = {"method": _check.choice(method, "method", METHODS)}
    if step is not None:
        integ["step"] = _check.positive(step, "step")
    _apply_adaptive(integ, dict(adaptive or {}, step=step))
    integ["duration"] = _check.non_negative(duration, "duration")
    if order is not None:
        integ["order"] = _check.integer(order, "order", 2, 8)
    run = {}
    if threads is not None:
        run["threads"] = _check.integer(threads, "threads", 1)
    if on_contact is not None:
        run["on_contact"] = _check.choice(on_contact, "on_contact", ("stop", "warn", "ignore"))
    return integ, run


def _periodic(periodic, name):
    """Three booleans, one per axis; ValueError naming the argument."""
    if (isinstance(periodic, (str, bytes)) or not hasattr(periodic, "__len__") or len(periodic) != 3
            or not all(isinstance(p, (bool, np.bool_)) for p in periodic)):
        raise ValueError(f"{name}: must be 3 booleans, one per axis, got {periodic!r}")
    return [bool(p) for p in periodic]


def _box(box):
    """The [box] table of from_arrays' ``box``: lower, upper (3 numbers), periodic (3 bools, default all true)."""
    if box is None:
        return None
    if not isinstance(box, dict):
        raise ValueError(f"box: must be None or a dict with lower, upper and periodic, got {box!r}")
    unknown = sorted(set(box) - {"lower", "upper", "periodic"})
    if unknown:
        raise ValueError(f"box: unknown key {unknown[0]!r}; allowed: lower, upper, periodic")
    table = {}
    for key in ("lower", "upper"):
        if key not in box:
            raise ValueError(f"box.{key}: missing (3 numbers)")
        table[key] = [float(x) for x in _check.vector3(box[key], f"box.{key}")]
    if "periodic" in box:
        table["periodic"] = _periodic(box["periodic"], "box.periodic")
    return table


def _check_name(name):
    if not isinstance(name, str) or not name:
        raise ValueError(f"name: must be a non-empty str, got {name!r}")
    return name


def _parse(text, name):
    try:
        return _core.parse_scenario(text, name)
    except ValueError as e:
        raise _value_error(e) from None


def _scenario(scenario, name="scenario"):
    if isinstance(scenario, Scenario):
        return scenario
    if isinstance(scenario, (str, os.PathLike)):
        return Scenario.from_toml(scenario)
    raise ValueError(f"{name}: must be an lgvi.Scenario or the path of a scenario file, got {scenario!r}")


# ---------------------------------------------------------------------------
# Running

def simulate(scenario, potential=None, *, forcing=None, control=None, check=True):
    """Run a scenario with the CLI's own run loop; returns an lgvi.Result.

    ``scenario``: an lgvi.Scenario or the path of a scenario file.
    ``potential``: None for the scenario's built-in potential (the run is
    then bit-identical to ``lgvi run`` and releases the GIL), or a potential
    written in Python: an ``lgvi.PythonPotential`` or a callable ``(x, q) ->
    (energy, force, torque)`` with q scalar-first (w, x, y, z) (it replaces
    the scenario's; see PythonPotential for what it costs per step).

    The Result holds numpy arrays of the written rows (``t``, ``x``, ``q``
    scalar-first (w, x, y, z), ``p``, ``w``, ``energy``, ``energy_error``,
    ``quat_norm_error``, ``L``, ``momentum_error``; ``columns`` by CSV header
    name) and ``summary``, the dict of the CLI's summary.json (the same
    except wall_seconds and ns_per_step; with a Python potential,
    summary["setup"]["potential"] is {"kind": "python"}).

    ``forcing``: an ``lgvi.PythonForcing`` or a callable ``(t, x, q, p, w) ->
    (force, torque)`` (force inertial, torque body frame) added to the
    scenario's ``[[forcing]]``; the rows then end with the column ``work``
    and ``energy_error`` is E - E0 - W. Methods lgvi and so3-lgvi only.

    ``control``: a control law ``(t, q, omega, wheel_speeds) -> torque`` in place of the PD law of the
    scenario's attitude controller through its reaction wheels (``[[forcing]] kind =
    "attitude-control"``, ``actuator = "wheels"``): q (4,) and omega (3,) are what the law sees (the
    ``[[sensor]]`` readings, or the truth), wheel_speeds (k,) the wheels' speeds relative to the body,
    the torque (3,) in body axes. It is called once per sample (the controller's ``period``), then
    scaled down to ``max_torque`` and split over the wheels (-A^+ M, or ``distribution``).

    A failed step (no root of the rotation equation, solver not converged,
    non-finite values) raises lgvi.IntegrationError, a RuntimeError whose
    ``result`` is the Result up to the last good step (``completed`` False),
    ``step`` the failed step's index k and ``time`` its t_k. With
    ``check=False`` that Result is returned instead. Ctrl-C stops the run
    with KeyboardInterrupt. Exceptions raised by a Python potential
    propagate unchanged.
    """
    sc = _scenario(scenario)
    core_pot = _potential.core_potential(potential)
    try:
        data, summary_text, completed, error, tables, columns = _core.simulate(
            sc._core, core_pot, _forcing.core_forcing(forcing), control)
    except ValueError as e:
        raise _value_error(e) from None
    summary = json.loads(summary_text)
    if core_pot is not None:
        summary["setup"]["potential"] = {"kind": "python", "function": repr(potential)}
    # A [[bodies]] scenario: its lists of bodies in the summary, or (beyond 10 000 bodies, or [output]
    # body_lists = "file") in a file the CLI writes beside it; this run writes none (the final state is the
    # arrays' last row, the names come from the scenario).
    if "body_lists" in summary:
        summary["body_lists"]["file"] = None
    result = Result(data, summary, sc.toml, columns=columns,
                    names=sc._core.body_names if "body_lists" in summary else None)
    # The side tables (the CLI's sensors.csv and wheels.csv): column name -> array.
    side = {file: {n: rows[:, j].copy() for j, n in enumerate(names)} for file, (names, rows) in tables.items()}
    result._sensors = side.get("sensors.csv", {})
    result._wheel_rows = side.get("wheels.csv", {})
    if not completed and check:
        e = IntegrationError(error)
        e.step = summary.get("steps", 0)
        e.time = summary.get("last_time", 0.0)
        e.result = result
        raise e
    return result


class Stepper:
    """Step a scenario one step (or n) at a time, for control loops that change forces between steps.

    ``Stepper(scenario, potential=None)`` starts at the scenario's initial
    state (k = 0) with its method and solver; ``potential`` as in
    lgvi.simulate (None: the scenario's built-in one). ``step()`` /
    ``step(n)`` advance; k steps give exactly simulate()'s rows (``row``).

    State, as numpy arrays: ``position`` x (3,), ``quaternion`` q (4,)
    **scalar-first (w, x, y, z)**, ``momentum`` p (3,), ``w`` = 2 J Omega
    (3,), ``omega`` Omega (3,), ``velocity`` (3,), ``rotation_matrix`` (3,
    3); time ``t`` = k h (never accumulated), step index ``k``; diagnostics
    ``energy``, ``energy_error`` (against k = 0), ``angular_momentum``,
    ``linear_momentum``, ``potential_energy``, ``force`` and ``torque`` at
    the current state; ``state`` (all as a dict).

    A [[bodies]] scenario of N bodies is stepped as a whole (``bodies`` is
    N): each per-body array gains a leading body axis, (N, 3), (N, 4) and
    (N, 3, 3), row a for body a in the scenario's order, both when read and
    when given to ``set_state``; the energy and the momenta are the
    system's totals, and ``row`` is the long format's N rows.

    Changing forces between steps:

    * ``set_potential(p)`` replaces the potential (a PythonPotential, a
      callable, or None for the scenario's own) from the current step on;
    * a Python potential may read parameters that you change between steps
      (a closure or an attribute); call ``refresh()`` after changing them, so
      the next step starts from forces evaluated with the new values (the
      integrator otherwise reuses the force at the current state, computed
      at the end of the previous step);
    * ``set_state(...)`` changes the state itself (an impulse:
      ``set_state(momentum=stepper.momentum + dp)``).

    On the Lagrangian side (method "lgvi-lagrangian") the next configuration
    is computed one step ahead, so a change of forces takes effect one step
    later. A failed step raises lgvi.IntegrationError and leaves the state at
    the last good step.
    """

    def __init__(self, scenario, potential=None, *, forcing=None):
        self._scenario = _scenario(scenario)
        self._potential = potential
        try:
            self._core = _core.Stepper(self._scenario._core, _potential.core_potential(potential),
                                       _forcing.core_forcing(forcing))
        except ValueError as e:
            raise _value_error(e) from None

    def step(self, n=1):
        """Take n >= 1 steps (default 1); IntegrationError on failure (the state stays at the last good step)."""
        self._core.step(_check.integer(n, "n", 0))

    def refresh(self):
        """Re-evaluate the potential at the current state (after changing what a Python potential reads)."""
        self._core.refresh()

    def set_potential(self, potential):
        """Replace the potential from the current step on: a PythonPotential, a callable (x, q) -> (energy,
        force, torque) with q scalar-first (w, x, y, z), or None for the scenario's own."""
        self._core.set_potential(_potential.core_potential(potential))
        self._potential = potential

    def set_state(self, position=None, quaternion=None, momentum=None, w=None, *, velocity=None, omega=None):
        """Replace parts of the state (the others stay); re-initializes the integrator there.

        ``position`` (3,), ``quaternion`` (4,) scalar-first (w, x, y, z) within
        1e-6 of unit norm (then normalized), ``momentum`` or ``velocity``,
        ``w`` or ``omega``; for N bodies (N, 3) and (N, 4), all bodies' at
        once. k and t are unchanged; energy_error stays relative to k = 0.
        """
        for a, b, va, vb in (("momentum", "velocity", momentum, velocity), ("w", "omega", w, omega)):
            if va is not None and vb is not None:
                raise ValueError(f"{a}, {b}: give one of them, not both")
        n = self._core.bodies
        if n == 1:
            x = None if position is None else _check.vector3(position, "position")
            q = None if quaternion is None else _check.quaternion(quaternion, "quaternion")
            p = None if momentum is None else _check.vector3(momentum, "momentum")
            if velocity is not None:
                p = self._scenario._core.body.mass * _check.vector3(velocity, "velocity")
            ww = None if w is None else _check.vector3(w, "w")
            if omega is not None:
                ww = 2.0 * (self._scenario._core.body.inertia @ _check.vector3(omega, "omega"))
        else:
            x = None if position is None else _check.array(position, "position", (n, 3))
            q = None
            if quaternion is not None:
                q = _check.array(quaternion, "quaternion", (n, 4))
                for a in range(n):
                    _core.check_quaternion(q[a], f"quaternion[{a}]")
            p = None if momentum is None else _check.array(momentum, "momentum", (n, 3))
            if velocity is not None:
                p = self._core.masses[:, None] * _check.array(velocity, "velocity", (n, 3))
            ww = None if w is None else _check.array(w, "w", (n, 3))
            if omega is not None:
                ww = 2.0 * np.einsum("aij,aj->ai", self._core.inertias, _check.array(omega, "omega", (n, 3)))
        try:
            self._core.set_state(x, q, p, ww)
        except ValueError as e:
            raise _value_error(e) from None

    @property
    def scenario(self):
        """The scenario (lgvi.Scenario)."""
        return self._scenario

    @property
    def potential(self):
        """The Python potential in use, or None for the scenario's built-in one."""
        return self._potential

    @property
    def bodies(self):
        """N, the number of bodies stepped (1 for a [body] scenario)."""
        return self._core.bodies

    @property
    def k(self):
        """Steps taken."""
        return self._core.k

    @property
    def t(self):
        """Time k h (never accumulated)."""
        return self._core.t

    @property
    def h(self):
        """Step size."""
        return self._core.h

    @property
    def position(self):
        """Centre of mass x (3,); (N, 3) for N bodies."""
        return self._core.position

    @property
    def quaternion(self):
        """Attitude q (4,), scalar-first (w, x, y, z); (N, 4) for N bodies."""
        return self._core.quaternion

    @property
    def momentum(self):
        """Linear momentum p (3,); (N, 3) for N bodies."""
        return self._core.momentum

    @property
    def velocity(self):
        """Velocity p / m (3,); (N, 3) for N bodies."""
        return self._core.velocity

    @property
    def w(self):
        """The paper's w = 2 J Omega (3,); (N, 3) for N bodies."""
        return self._core.w

    @property
    def omega(self):
        """Body angular velocity Omega = J^-1 w / 2 (3,); (N, 3) for N bodies."""
        return self._core.omega

    @property
    def rotation_matrix(self):
        """R = pi(q) (3x3), body to inertial frame; (N, 3, 3) for N bodies."""
        return self._core.rotation_matrix

    @property
    def energy(self):
        """Total energy at the current state (the system's for N bodies)."""
        return self._core.energy

    @property
    def energy_error(self):
        """Energy minus the energy at k = 0, minus the forcing's work (E - E0 - W)."""
        return self._core.energy - self._core.initial_energy - self._core.work

    @property
    def work(self):
        """The work done by the forcing since k = 0 (0 without forcing)."""
        return self._core.work

    @property
    def potential_energy(self):
        """V at the current state."""
        return self._core.potential_energy

    @property
    def force(self):
        """Force -dV/dx at the current state (3,), inertial frame; (N, 3) for N bodies."""
        return self._core.force

    @property
    def torque(self):
        """Body-frame torque M at the current state (3,); (N, 3) for N bodies."""
        return self._core.torque

    @property
    def angular_momentum(self):
        """Total angular momentum about the origin, L = sum_a x_a cross p_a + R_a w_a / 2 (3,)."""
        return self._core.angular_momentum

    @property
    def linear_momentum(self):
        """Total linear momentum P = sum_a p_a (3,)."""
        return self._core.linear_momentum

    @property
    def solver_iterations(self):
        """Iterations of the last step's rotation solve."""
        return self._core.solver_iterations

    @property
    def row(self):
        """The 21 trajectory columns at the current step (lgvi.COLUMNS order; 22 with "work" when forced), exactly
        as simulate() writes them; for N bodies the long format's N rows (lgvi.BODIES_COLUMNS order, with
        "work" when forced; not the temperature and pressure), shape (N, 26) or (N, 27)."""
        return self._core.row()

    @property
    def state(self):
        """The current state as a dict: t, k, position, quaternion (scalar-first (w, x, y, z)), momentum, w, omega."""
        c = self._core
        return {"t": c.t, "k": c.k, "position": c.position, "quaternion": c.quaternion, "momentum": c.momentum,
                "w": c.w, "omega": c.omega}

    def __repr__(self):
        return f"<lgvi.Stepper {self._scenario.name!r}: k = {self.k}, t = {self.t:.6g}>"
