"""Result: a trajectory with its diagnostics and summary, from lgvi.simulate()
or lgvi.load(). Pure numpy (no compiled code), so that lgvi.plot and
lgvi.load work from the source tree too."""

import json
import os
import warnings

import numpy as np

from . import _attitude
from ._columns import (BODIES_COLUMNS, COLUMNS, FORCED_BODIES_COLUMNS, FORCED_COLUMNS, HEADER,  # noqa: F401
                       THERMO_COLUMNS, WHEEL_QUANTITIES, bodies_columns, bodies_columns_of,
                       body_of, wheel_columns)


class _RunSummary:
    """What Result and SystemResult share: the summary's verdict and the number of written steps."""

    @property
    def completed(self):
        """Whether every planned step was taken (summary["completed"])."""
        return bool(self.summary.get("completed", True))

    @property
    def error(self):
        """Why the run stopped early; "" if it completed."""
        return self.summary.get("error", "")

    @property
    def sensors(self):
        """What the attitude controller's sensors ([[sensor]]) read at each of its samples: name -> (S,) array,
        the names of the CLI's sensors.csv ("t", "gyro.wx", ..., "gyro.bias_x", ..., "star_tracker.qw", ...);
        {} without sensors."""
        return getattr(self, "_sensors", {})

    def __len__(self):
        return self.data.shape[0]


class _Attitude:
    """Attitude helpers shared by Result (arrays (rows, ...)) and SystemResult
    (arrays (steps, N, ...), every body): they use the subclass's x, p and q."""

    def rotation_matrices(self):
        """R = pi(q) at every row, shape q.shape[:-1] + (3, 3): (rows, 3, 3) for a
        Result, (steps, N, 3, 3) for a SystemResult. Body frame -> inertial frame
        (column j: body axis j)."""
        return _attitude.rotation_matrices(self.q)

    def euler_angles(self, seq="ZYX", degrees=False):
        """Euler angles of R at every row (and body), shape q.shape[:-1] + (3,), in the order of `seq`.

        Upper case `seq` is intrinsic (R = R_A(a) R_B(b) R_C(c) for "ABC",
        default "ZYX": yaw, pitch, roll about the inertial axes' z, then the
        new y, then the new x); lower case is extrinsic (scipy's convention).
        Radians unless degrees=True."""
        return _attitude.euler_angles(self.rotation_matrices(), seq, degrees)

    def lvlh_angles(self, degrees=True):
        """Roll, pitch, yaw of each body in the LVLH frame of its own orbit about the origin,
        shape q.shape[:-1] + (3,).

        LVLH: x radial (out from the central source at the origin), z the
        orbit normal x cross p / |x cross p|, y = z cross x (along-track). The
        attitude in it is R_LVLH^T R = Rz(pitch) Ry(roll) Rx(yaw) (pitch about
        the orbit normal, then roll about the new y, then yaw about the new
        x), as the scenario key [initial] attitude = { frame = "lvlh", roll,
        pitch, yaw }. Degrees unless degrees=False; pitch and yaw in (-180,
        180], roll in [-90, 90]. ValueError where a body's position and
        momentum are parallel or zero (no orbit plane)."""
        return _attitude.lvlh_angles(self.x, self.p, self.q, degrees)


class Result(_RunSummary, _Attitude):
    """A trajectory: one row per written step (every `every` steps, plus the first and the last).

    Arrays (views into ``data``, the (N, 21) float64 table with the columns of
    the CLI's trajectory.csv):

    * ``t`` (N,): time k h;
    * ``x`` (N, 3): centre of mass;
    * ``q`` (N, 4): attitude, unit quaternions **scalar-first (w, x, y, z)**;
    * ``p`` (N, 3): linear momentum m v;
    * ``w`` (N, 3): the paper's w = 2 J Omega (body angular momentum is w / 2);
    * ``energy``, ``energy_error`` (E(t) - E(0)), ``quat_norm_error`` (|q| - 1) (N,);
    * ``L`` (N, 3): total angular momentum x cross p + R w / 2; ``momentum_error`` |L(t) - L(0)| (N,).

    ``columns`` maps each CSV header name ("t", "x", ..., "momentum_error")
    to its 1-D column. ``summary`` is the run's summary (the CLI's
    summary.json as a dict); ``completed`` and ``error`` come from it.
    ``scenario_toml`` is the scenario's TOML text (None if unknown).
    """

    def __init__(self, data, summary=None, scenario_toml=None, source=None):
        data = np.asarray(data, dtype=float)
        wheels = wheel_columns(summary or {})
        widths = (len(COLUMNS) + len(wheels), len(FORCED_COLUMNS) + len(wheels))
        if data.ndim != 2 or data.shape[1] not in widths:
            raise ValueError(f"data: must have shape (N, {len(COLUMNS)}), or (N, {len(FORCED_COLUMNS)}) with the "
                             f"forcing's work, or those and the reaction wheels' columns the summary names, got shape "
                             f"{data.shape}")
        #: The (N, 21) table; (N, 22) with the column "work" for a forced scenario; then 3 per reaction wheel.
        self.data = data
        names = (FORCED_COLUMNS if data.shape[1] == len(FORCED_COLUMNS) + len(wheels) else COLUMNS) + wheels
        #: Column name -> 1-D array (views into data), in the CSV header's order.
        self.columns = {name: data[:, i] for i, name in enumerate(names)}
        #: The summary dict (the CLI's summary.json).
        self.summary = dict(summary or {})
        #: The scenario's TOML text, or None.
        self.scenario_toml = scenario_toml
        #: Where it was loaded from (a path), or None for a run in memory.
        self.source = source
        self._sensors = {}

    # Trajectory ------------------------------------------------------------
    @property
    def t(self):
        """Time t_k = k h of each row, shape (N,)."""
        return self.data[:, 0]

    @property
    def wheels(self):
        """The reaction wheels' columns: name -> {"speed", "momentum", "torque"} -> (N,) arrays (speed relative
        to the body, axial momentum, the torque applied over the step from the row's time); {} without wheels."""
        out = {}
        for w in body_of(self.summary).get("wheels") or []:
            out[w["name"]] = {q: self.columns[f"{w['name']}.{q}"] for q in WHEEL_QUANTITIES}
        return out

    @property
    def x(self):
        """Centre of mass, shape (N, 3)."""
        return self.data[:, 1:4]

    @property
    def q(self):
        """Attitude quaternions, shape (N, 4), scalar-first (w, x, y, z)."""
        return self.data[:, 4:8]

    @property
    def p(self):
        """Linear momentum p = m v, shape (N, 3)."""
        return self.data[:, 8:11]

    @property
    def w(self):
        """The paper's w = 2 J Omega, shape (N, 3)."""
        return self.data[:, 11:14]

    @property
    def energy(self):
        """Total energy, shape (N,)."""
        return self.data[:, 14]

    @property
    def energy_error(self):
        """E(t) - E(0), shape (N,)."""
        return self.data[:, 15]

    @property
    def quat_norm_error(self):
        """|q| - 1, shape (N,)."""
        return self.data[:, 16]

    @property
    def L(self):
        """Total angular momentum about the origin, shape (N, 3)."""
        return self.data[:, 17:20]

    @property
    def momentum_error(self):
        """|L(t) - L(0)|, shape (N,)."""
        return self.data[:, 20]

    @property
    def omega(self):
        """Body angular velocity Omega = J^-1 w / 2, shape (N, 3) (needs the body's inertia in the summary; J's
        pseudo-inverse for a linear body or a point, which has no rotation about its axis). With reaction wheels,
        Omega = J_s^-1 (w / 2 - h_w): J_s = J - sum_i j_i a_i a_i^T, h_w = sum_i eta_i a_i (the momentum columns)."""
        body = body_of(self.summary)
        inertia = body.get("inertia")
        if inertia is None:
            raise ValueError("omega: the summary has no body inertia (setup.body.inertia)")
        inertia = np.asarray(inertia, dtype=float)
        wheels = body.get("wheels") or []
        if wheels:
            axes = np.array([w["axis"] for w in wheels], dtype=float)
            reduced = inertia - sum(w["inertia"] * np.outer(a, a) for w, a in zip(wheels, axes))
            h_w = np.column_stack([self.columns[f"{w['name']}.momentum"] for w in wheels]) @ axes
            return np.linalg.solve(reduced, (0.5 * self.w - h_w).T).T
        if body.get("rotational_dof", 3) != 3:
            return 0.5 * (np.linalg.pinv(inertia) @ self.w.T).T
        return 0.5 * np.linalg.solve(inertia, self.w.T).T

    def __repr__(self):
        name = self.summary.get("scenario", "?")
        t_end = self.t[-1] if len(self) else float("nan")
        state = "completed" if self.completed else "NOT completed"
        return f"<lgvi.Result {name!r}: {len(self)} rows, t in [0, {t_end:.6g}], {state}>"

    # Output ----------------------------------------------------------------
    def save(self, run_dir):
        """Write a run folder like the CLI's: trajectory.csv (17 significant
        digits, exact round trip), summary.json, if known scenario.toml, and with
        sensors their readings, sensors.csv. `lgvi.load` and `python3 -m lgvi.plot`
        read it. Returns run_dir."""
        os.makedirs(run_dir, exist_ok=True)
        np.savetxt(os.path.join(run_dir, "trajectory.csv"), self.data, fmt="%.17g", delimiter=",",
                   header=",".join(self.columns), comments="")
        with open(os.path.join(run_dir, "summary.json"), "w", encoding="utf-8") as f:
            json.dump(self.summary, f, indent=2)
            f.write("\n")
        if self.scenario_toml is not None:
            with open(os.path.join(run_dir, "scenario.toml"), "w", encoding="utf-8") as f:
                f.write(self.scenario_toml)
        if self._sensors:
            names = list(self._sensors)
            np.savetxt(os.path.join(run_dir, "sensors.csv"), np.column_stack([self._sensors[n] for n in names]),
                       fmt="%.17g", delimiter=",", header=",".join(names), comments="")
        return run_dir

    def draw_figures(self, out_dir):
        """Deprecated: use ``lgvi.plot.draw_figures(result, out_dir)`` (the same figures; returns the paths)."""
        return _deprecated_draw_figures(self, out_dir)


class SystemResult(_RunSummary, _Attitude):
    """The trajectory of a many-body ([[bodies]]) scenario, from lgvi.simulate() or lgvi.load().

    ``data`` is the (steps, N, 26) float64 array with the columns BODIES_COLUMNS
    (steps: the written steps; N: the bodies, in scenario order). Arrays:

    * ``t`` (steps,): time k h;
    * ``x``, ``p``, ``w`` (steps, N, 3): centres of mass, linear momenta, the
      paper's w = 2 J Omega of every body; ``q`` (steps, N, 4): attitudes,
      scalar-first (w, x, y, z); ``quat_norm_error`` (steps, N): |q| - 1;
    * the system's ``energy``, ``energy_error``, ``linear_momentum_error``,
      ``momentum_error`` (steps,), and ``P``, ``L`` (steps, 3): total linear
      momentum and total angular momentum about the origin.

    ``names`` are the bodies' names (given, or from the summary's final_bodies; body0, body1, ... if neither
    has them); ``summary`` the run's summary dict.
    """

    def __init__(self, data, summary=None, scenario_toml=None, source=None, columns=None, names=None):
        data = np.asarray(data, dtype=float)
        widths = range(len(BODIES_COLUMNS), len(FORCED_BODIES_COLUMNS) + len(THERMO_COLUMNS) + 1)
        if data.ndim == 2:  # the long format's rows: regroup them by step
            if data.shape[1] not in widths:
                raise ValueError(f"data: must have {len(BODIES_COLUMNS)} columns (and work, temperature, pressure "
                                 f"after them as the run has them), got shape {data.shape}")
            bodies = int(data[:, 1].max()) + 1 if len(data) else 0
            if bodies == 0 or len(data) % bodies:
                raise ValueError(f"data: {len(data)} rows are not whole steps of {bodies} bodies")
            data = data.reshape(len(data) // bodies, bodies, data.shape[1])
        if data.ndim != 3 or data.shape[2] not in widths:
            raise ValueError(f"data: must have shape (steps, N, {len(BODIES_COLUMNS)}), got shape {data.shape}")
        #: The (steps, N, 26) array; with "work" for a forced scenario, then "temperature" (and "pressure") for a
        #: molecular run, after them.
        self.data = data
        self.summary = dict(summary or {})
        self.scenario_toml = scenario_toml
        self.source = source
        if names is None:
            names = [b.get("name") for b in self.summary.get("final_bodies", [])]
        #: The bodies' names, in scenario order.
        self.names = names if len(names) == data.shape[1] else [f"body{i}" for i in range(data.shape[1])]
        if columns is not None:
            names = bodies_columns(columns)
            if names is None or len(names) != data.shape[2]:
                raise ValueError(f"columns: {','.join(columns)} are not the long format's for {data.shape[2]} values")
        elif self.summary:
            names = bodies_columns_of(data.shape[2], self.summary)
        else:  # no summary: the width says whether the forcing's work is there
            names = (BODIES_COLUMNS, FORCED_BODIES_COLUMNS)[data.shape[2] - len(BODIES_COLUMNS)] \
                if data.shape[2] <= len(FORCED_BODIES_COLUMNS) else None
            if names is None:
                raise ValueError(f"data: {data.shape[2]} columns need the run's summary (or columns=) to name them")
        #: Column name -> array: (steps, N) for per-body columns, (steps,) for the system's.
        per_body = BODIES_COLUMNS.index("energy")  # the body's columns come first, then the system's
        self.columns = {name: (data[:, :, i] if i < per_body else data[:, 0, i]) for i, name in enumerate(names)}
        self._wheel_rows = {}  # the CLI's wheels.csv: column name -> array
        self._sensors = {}  # the CLI's sensors.csv (a system of one body with the wheel controller)

    @property
    def wheels(self):
        """The reaction wheels ([[bodies.wheel]]) at the written steps: body name -> wheel name -> {"speed",
        "momentum", "torque"} -> (steps,) arrays (speed relative to the body, axial momentum, the torque
        applied over the step from that time; the CLI's wheels.csv); {} without wheels."""
        rows = self._wheel_rows
        if not rows or len(rows.get("t", ())) == 0:
            return {}
        out, counts = {}, {}
        for entry in self.summary.get("wheels") or []:  # body by body, each body's wheels in order
            body = entry["body"]
            b, w = self.names.index(body), counts.get(body, 0)
            counts[body] = w + 1
            at = (rows["body"] == b) & (rows["wheel"] == w)
            out.setdefault(body, {})[entry["name"]] = {q: rows[q][at] for q in WHEEL_QUANTITIES}
        return out

    @property
    def temperature(self):
        """The kinetic temperature 2 K / (6 N - 3) (k_B = 1) of each written step, (steps,): a molecular run's
        (the summary's "thermodynamics"); KeyError otherwise."""
        return self.columns["temperature"]

    @property
    def pressure(self):
        """The pressure of the rigid molecules (2 K_trans + W) / 3V of each written step, (steps,): a molecular
        run's in a box periodic along every axis; KeyError otherwise."""
        return self.columns["pressure"]

    @property
    def bodies(self):
        """The number of bodies N."""
        return self.data.shape[1]

    t = property(lambda self: self.data[:, 0, 0], doc="Time t_k = k h of each written step, shape (steps,).")
    x = property(lambda self: self.data[:, :, 2:5], doc="Centres of mass, shape (steps, N, 3).")
    q = property(lambda self: self.data[:, :, 5:9], doc="Attitudes, shape (steps, N, 4), scalar-first.")
    p = property(lambda self: self.data[:, :, 9:12], doc="Linear momenta, shape (steps, N, 3).")
    w = property(lambda self: self.data[:, :, 12:15], doc="The paper's w = 2 J Omega, shape (steps, N, 3).")
    quat_norm_error = property(lambda self: self.data[:, :, 15], doc="|q| - 1 of every body, (steps, N).")
    energy = property(lambda self: self.data[:, 0, 16], doc="Total energy, shape (steps,).")
    energy_error = property(lambda self: self.data[:, 0, 17], doc="E(t) - E(0), shape (steps,).")
    P = property(lambda self: self.data[:, 0, 18:21], doc="Total linear momentum, shape (steps, 3).")
    linear_momentum_error = property(lambda self: self.data[:, 0, 21],
                                     doc="|P(t) - P(0)| / sum_a |p_a(0)|, shape (steps,).")
    L = property(lambda self: self.data[:, 0, 22:25], doc="Total angular momentum about the origin, (steps, 3).")
    momentum_error = property(lambda self: self.data[:, 0, 25], doc="|L(t) - L(0)|, shape (steps,).")


    def __repr__(self):
        return (f"<lgvi.SystemResult {self.bodies} bodies, {len(self)} steps written, "
                f"t = {self.t[0] if len(self) else 0:g} .. {self.t[-1] if len(self) else 0:g}>")

    def draw_figures(self, out_dir):
        """Deprecated: use ``lgvi.plot.draw_figures(result, out_dir)`` (the same figures; returns the paths)."""
        return _deprecated_draw_figures(self, out_dir)


def _deprecated_draw_figures(result, out_dir):
    """Result.draw_figures and SystemResult.draw_figures, kept working for code that calls them.

    The data layer does not depend on the figure layer (lgvi.plot imports this module, not the
    reverse): this shim is the one upward import left in the package, named as such in
    tests/python/test_import_layers.py, and goes when the methods go."""
    warnings.warn(f"{type(result).__name__}.draw_figures is deprecated: call lgvi.plot.draw_figures(result, "
                  f"out_dir) (the same figures)", DeprecationWarning, stacklevel=3)
    from . import plot  # deprecated upward import (see the docstring)
    return plot.draw_figures(result, out_dir)
