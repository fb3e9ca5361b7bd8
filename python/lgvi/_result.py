"""Result: a run's trajectory with its diagnostics and summary, from lgvi.simulate() or lgvi.load(), for one
body or many. Pure numpy (no compiled code), so that lgvi.plot and lgvi.load work from the source tree too."""

import json
import os
import warnings

import numpy as np

from . import _attitude
from ._columns import (BODIES_COLUMNS, COLUMNS, FORCED_BODIES_COLUMNS, FORCED_COLUMNS, HEADER,  # noqa: F401
                       THERMO_COLUMNS, WHEEL_QUANTITIES, bodies_columns, bodies_columns_of, body_of,
                       single_columns, wheel_columns)

#: The two row layouts of a trajectory ([output] layout): one row a written step with one body's columns
#: (COLUMNS: a [body] scenario's default), or one row a written step and body (BODIES_COLUMNS: [[bodies]]).
LAYOUTS = ("single-body", "long")

# Where each body's quantities are in a row of either layout: name -> (first column, width); a width of 0 is
# one column without an axis of its own.
_BODY_SLICES = {
    "single-body": {"x": (1, 3), "q": (4, 4), "p": (8, 3), "w": (11, 3), "quat_norm_error": (16, 0)},
    "long": {"x": (2, 3), "q": (5, 4), "p": (9, 3), "w": (12, 3), "quat_norm_error": (15, 0)},
}
# The system's quantities, the same in every row of a step of the long layout.
_SYSTEM_SLICES = {
    "single-body": {"energy": (14, 0), "energy_error": (15, 0), "L": (17, 3), "momentum_error": (20, 0)},
    "long": {"energy": (16, 0), "energy_error": (17, 0), "P": (18, 3), "linear_momentum_error": (21, 0),
             "L": (22, 3), "momentum_error": (25, 0)},
}


#: The long layout's widths: BODIES_COLUMNS, then "work", "temperature", "pressure" as the run has them.
_LONG_WIDTHS = range(len(BODIES_COLUMNS), len(FORCED_BODIES_COLUMNS) + len(THERMO_COLUMNS) + 1)


def _take(table, first, width):
    return table[..., first] if width == 0 else table[..., first:first + width]


class BodyTrajectory:
    """One body of a Result at its written steps: ``name``, ``t`` (steps,) and the views ``x``, ``p``, ``w``
    (steps, 3), ``q`` (steps, 4, scalar-first), ``quat_norm_error`` (steps,) into the result's data, the same
    for either layout."""

    def __init__(self, result, index):
        self.index = index
        self.name = result.names[index]
        self.t = result.t
        for quantity in _BODY_SLICES[result.layout]:
            setattr(self, quantity, result.per_body(quantity)[:, index])

    def __repr__(self):
        return f"<lgvi.BodyTrajectory {self.name!r}: {len(self.t)} steps>"


class Result:
    """A run's trajectory, one row (and body) per written step (every `every` steps, plus the first and the
    last), for one body or many; from lgvi.simulate() or lgvi.load().

    A trajectory has one of two row layouts (``layout``, the scenario's ``[output] layout``):

    * ``"single-body"`` (a [body] scenario's): ``data`` is the (steps, 21) float64 table with the columns of
      the CLI's trajectory.csv (COLUMNS; then "work" under a forcing and three per reaction wheel);
      ``x``, ``p``, ``w`` are (steps, 3), ``q`` (steps, 4), ``quat_norm_error`` (steps,);
    * ``"long"`` (a [[bodies]] scenario's): ``data`` is (steps, N, 26) (BODIES_COLUMNS; then "work" under a
      forcing, then "temperature" and "pressure" for a molecular run); ``x``, ``p``, ``w`` are
      (steps, N, 3), ``q`` (steps, N, 4), ``quat_norm_error`` (steps, N).

    The same in either layout: ``bodies`` (N, 1 for the single-body layout) and ``names``; ``per_body(name)``,
    a body's quantity with the body axis, (steps, N, ...), and ``body(i)``, one body's (steps, ...) arrays
    (a BodyTrajectory, by index or name); the system's ``t`` (time k h), ``energy``, ``energy_error``
    (E(t) - E(0); E - E0 - W under a forcing), ``L`` (total angular momentum about the origin),
    ``momentum_error`` |L(t) - L(0)|, ``P`` (total linear momentum) and ``linear_momentum_error``
    |P(t) - P(0)| / sum_a |p_a(0)| (computed from p in the single-body layout, which has no columns for them),
    all (steps,) or (steps, 3). Quaternions are **scalar-first (w, x, y, z)**; w is the paper's w = 2 J Omega.

    ``columns`` maps each column name of the file's header to its array: (steps,), or (steps, N) for a
    body's column of the long layout. ``summary`` is the run's summary (the CLI's summary.json as a dict);
    ``completed`` and ``error`` come from it. ``scenario_toml`` is the scenario's TOML text (None if unknown),
    ``source`` where it was loaded from.

    ``Result(data, summary, ...)`` takes either layout's table (the long one also as its 2-D rows, one row a
    step and body). The layout is that of ``columns`` (the header's names) when given, else ``layout``, else
    what the data's shape says (a 3-D array is the long layout's; a width both layouts can have, that of a
    summary of [[bodies]], the long layout, or of [body], the single-body layout).
    """

    def __init__(self, data, summary=None, scenario_toml=None, source=None, columns=None, names=None, layout=None):
        data = np.asarray(data, dtype=float)
        self.summary = dict(summary or {})
        #: The scenario's TOML text, or None.
        self.scenario_toml = scenario_toml
        #: Where it was loaded from (a path), or None for a run in memory.
        self.source = source
        self._sensors = {}
        self._wheel_rows = {}  # the long layout's wheels.csv: column name -> array
        if layout is not None and layout not in LAYOUTS:
            raise ValueError(f"layout: must be one of {', '.join(map(repr, LAYOUTS))}, got {layout!r}")
        header = None
        if columns is not None:
            columns = tuple(columns)
            if single_columns(columns) is not None:
                header, layout = columns, "single-body"
            elif bodies_columns(columns) is not None:
                header, layout = columns, "long"
            else:
                raise ValueError(f"columns: {','.join(columns)} are neither layout's (single-body: "
                                 f"{','.join(COLUMNS)},...; long: {','.join(BODIES_COLUMNS)},...)")
        if layout is None:
            # The width tells, but where both layouts have it (the single-body layout's reaction wheels), the
            # summary: a [[bodies]] scenario's default is the long layout.
            width = data.shape[-1] if data.ndim in (2, 3) else None
            fits_single, fits_long = width in self._single_widths(), width in _LONG_WIDTHS
            if data.ndim == 3 or (fits_long and not fits_single):
                layout = "long"
            elif fits_long and fits_single:
                layout = "long" if self._many_body_summary() else "single-body"
            else:
                layout = "single-body"  # (or neither, which the single-body layout's check reports)
        #: "single-body" or "long": the trajectory's row layout.
        self.layout = layout
        if layout == "single-body":
            self._init_single(data, header)
        else:
            self._init_long(data, header, names)

    # The two layouts' tables ------------------------------------------------
    def _many_body_summary(self):
        return "bodies" in (self.summary.get("setup") or {}) or "body_lists" in self.summary

    def _single_widths(self):
        wheels = len(wheel_columns(self.summary))
        return (len(COLUMNS) + wheels, len(FORCED_COLUMNS) + wheels)

    def _init_single(self, data, header):
        if header is None:
            wheels = wheel_columns(self.summary)
            widths = self._single_widths()
            if data.ndim != 2 or data.shape[1] not in widths:
                raise ValueError(f"data: must have shape (N, {len(COLUMNS)}), or (N, {len(FORCED_COLUMNS)}) with "
                                 f"the forcing's work, or those and the reaction wheels' columns the summary names, "
                                 f"got shape {data.shape}")
            header = (FORCED_COLUMNS if data.shape[1] == widths[1] else COLUMNS) + wheels
        elif data.ndim != 2 or data.shape[1] != len(header):
            raise ValueError(f"data: must have shape (N, {len(header)}) for the columns {','.join(header)}, got "
                             f"shape {data.shape}")
        #: The layout's table: (steps, columns) in the single-body layout, (steps, N, columns) in the long one.
        self.data = data
        #: The bodies' names, in scenario order.
        self.names = [body_of(self.summary).get("name") or self.summary.get("scenario") or "body"]
        final = self.summary.get("final_bodies") or []
        if len(final) == 1 and final[0].get("name"):  # a [[bodies]] scenario of one body
            self.names = [final[0]["name"]]
        #: Column name -> array (views into data), in the header's order.
        self.columns = {name: data[:, i] for i, name in enumerate(header)}

    def _init_long(self, data, header, names):
        widths = _LONG_WIDTHS
        if data.ndim == 2:  # the long layout's rows: regroup them by step
            if data.shape[1] not in widths:
                raise ValueError(f"data: must have {len(BODIES_COLUMNS)} columns (and work, temperature, pressure "
                                 f"after them as the run has them), got shape {data.shape}")
            bodies = int(data[:, 1].max()) + 1 if len(data) else 0
            if bodies == 0 or len(data) % bodies:
                raise ValueError(f"data: {len(data)} rows are not whole steps of {bodies} bodies")
            data = data.reshape(len(data) // bodies, bodies, data.shape[1])
        if data.ndim != 3 or data.shape[2] not in widths:
            raise ValueError(f"data: must have shape (steps, N, {len(BODIES_COLUMNS)}), got shape {data.shape}")
        self.data = data
        if names is None:
            names = [b.get("name") for b in self.summary.get("final_bodies", [])]
        self.names = list(names) if len(names) == data.shape[1] else [f"body{i}" for i in range(data.shape[1])]
        if header is not None:
            if len(header) != data.shape[2]:
                raise ValueError(f"columns: {','.join(header)} are not the long format's for {data.shape[2]} values")
        elif self.summary:
            header = bodies_columns_of(data.shape[2], self.summary)
        else:  # no summary: the width says whether the forcing's work is there
            header = (BODIES_COLUMNS, FORCED_BODIES_COLUMNS)[data.shape[2] - len(BODIES_COLUMNS)] \
                if data.shape[2] <= len(FORCED_BODIES_COLUMNS) else None
            if header is None:
                raise ValueError(f"data: {data.shape[2]} columns need the run's summary (or columns=) to name them")
        per_body = BODIES_COLUMNS.index("energy")  # the body's columns come first, then the system's
        self.columns = {name: (data[:, :, i] if i < per_body else data[:, 0, i]) for i, name in enumerate(header)}

    def _system_table(self):
        """The table whose rows hold the system's columns: data, or body 0's rows of the long layout."""
        return self.data if self.layout == "single-body" else self.data[:, 0, :]

    # The same in either layout -------------------------------------------
    @property
    def bodies(self):
        """The number of bodies N (1 in the single-body layout)."""
        return 1 if self.layout == "single-body" else self.data.shape[1]

    def per_body(self, quantity):
        """A body's quantity ("x", "q", "p", "w", "quat_norm_error") with the body axis in either layout:
        (steps, N, 3) or (steps, N, 4), (steps, N) for quat_norm_error; views into data."""
        slices = _BODY_SLICES[self.layout]
        if quantity not in slices:
            raise ValueError(f"quantity: must be one of {', '.join(map(repr, slices))}, got {quantity!r}")
        values = _take(self.data, *slices[quantity])
        return values[:, None] if self.layout == "single-body" else values

    def body(self, which):
        """One body's trajectory (BodyTrajectory: t, x, q, p, w, quat_norm_error as (steps, ...) arrays), by
        its index 0 .. N - 1 or its name."""
        if isinstance(which, str):
            if which not in self.names:
                raise ValueError(f"body: no body is named {which!r} (names: {', '.join(self.names[:5])}"
                                 f"{', ...' if len(self.names) > 5 else ''})")
            return BodyTrajectory(self, self.names.index(which))
        index = int(which)
        if not 0 <= index < self.bodies:
            raise ValueError(f"body: index {which} is not in 0 .. {self.bodies - 1}")
        return BodyTrajectory(self, index)

    @property
    def t(self):
        """Time t_k = k h of each written step, shape (steps,)."""
        return self._system_table()[:, 0]

    def _body_quantity(self, quantity):
        return _take(self.data, *_BODY_SLICES[self.layout][quantity])

    x = property(lambda self: self._body_quantity("x"),
                 doc="Centres of mass: (steps, 3) in the single-body layout, (steps, N, 3) in the long one.")
    q = property(lambda self: self._body_quantity("q"),
                 doc="Attitudes, scalar-first (w, x, y, z): (steps, 4) or (steps, N, 4).")
    p = property(lambda self: self._body_quantity("p"), doc="Linear momenta p = m v: (steps, 3) or (steps, N, 3).")
    w = property(lambda self: self._body_quantity("w"),
                 doc="The paper's w = 2 J Omega: (steps, 3) or (steps, N, 3).")
    quat_norm_error = property(lambda self: self._body_quantity("quat_norm_error"),
                               doc="|q| - 1: (steps,) or (steps, N).")

    def _system_quantity(self, quantity):
        return _take(self._system_table(), *_SYSTEM_SLICES[self.layout][quantity])

    energy = property(lambda self: self._system_quantity("energy"), doc="Total energy, shape (steps,).")
    energy_error = property(lambda self: self._system_quantity("energy_error"),
                            doc="E(t) - E(0) (E - E0 - W under a forcing), shape (steps,).")
    L = property(lambda self: self._system_quantity("L"),
                 doc="Total angular momentum about the origin, shape (steps, 3).")
    momentum_error = property(lambda self: self._system_quantity("momentum_error"),
                              doc="|L(t) - L(0)|, shape (steps,).")

    @property
    def P(self):
        """Total linear momentum, shape (steps, 3) (the one body's p in the single-body layout)."""
        return self.p if self.layout == "single-body" else self._system_quantity("P")

    @property
    def linear_momentum_error(self):
        """|P(t) - P(0)| / sum_a |p_a(0)| (absolute when every body starts at rest), shape (steps,); computed
        from p in the single-body layout, which has no column for it."""
        if self.layout == "long":
            return self._system_quantity("linear_momentum_error")
        change = np.linalg.norm(self.p - self.p[:1], axis=1)
        scale = float(np.linalg.norm(self.p[0])) if len(self) else 0.0
        return change / scale if scale > 0.0 else change

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
        return self._sensors

    @property
    def wheels(self):
        """The reaction wheels at the written steps, {} without wheels. In the single-body layout (the
        trajectory's columns NAME.speed, NAME.momentum, NAME.torque): wheel name -> {"speed", "momentum",
        "torque"} -> (steps,) arrays. In the long layout (the CLI's wheels.csv): body name -> wheel name ->
        the same. Speed relative to the body, axial momentum, the torque applied over the step from that
        time."""
        if self.layout == "single-body":
            names = [n[:-len(".speed")] for n in self.columns if n.endswith(".speed")]
            return {n: {q: self.columns[f"{n}.{q}"] for q in WHEEL_QUANTITIES} for n in names}
        rows = self._wheel_rows
        if not rows or len(rows.get("t", ())) == 0:
            return {}
        out, counts = {}, {}
        for entry in self.summary.get("wheels") or []:  # body by body, each body's wheels in order
            body = entry.get("body", self.names[0])  # (a [body] scenario's entries name no body)
            b, w = self.names.index(body), counts.get(body, 0)
            counts[body] = w + 1
            at = (rows["body"] == b) & (rows["wheel"] == w)
            out.setdefault(body, {})[entry["name"]] = {q: rows[q][at] for q in WHEEL_QUANTITIES}
        return out

    @property
    def omega(self):
        """Body angular velocity Omega = J^-1 w / 2 of the single-body layout's body, shape (steps, 3) (needs
        the body's inertia in the summary; J's pseudo-inverse for a linear body or a point, which has no
        rotation about its axis). With reaction wheels, Omega = J_s^-1 (w / 2 - h_w): J_s = J - sum_i j_i a_i
        a_i^T, h_w = sum_i eta_i a_i (the momentum columns). The long layout: ValueError (each body's inertia
        is in lgvi.load_bodies(run)'s set-up)."""
        if self.layout != "single-body":
            raise ValueError("omega: the single-body layout's; for a system, Omega_a = J_a^-1 w_a / 2 with each "
                             "body's inertia from lgvi.load_bodies(run)")
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

    # Attitude --------------------------------------------------------------
    def rotation_matrices(self):
        """R = pi(q) at every row (and body), shape q.shape[:-1] + (3, 3): (steps, 3, 3) in the single-body
        layout, (steps, N, 3, 3) in the long one. Body frame -> inertial frame (column j: body axis j)."""
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

    def __len__(self):
        return self.data.shape[0]

    def __repr__(self):
        name = self.summary.get("scenario", "?")
        t_end = self.t[-1] if len(self) else float("nan")
        state = "completed" if self.completed else "NOT completed"
        bodies = "1 body" if self.bodies == 1 else f"{self.bodies} bodies"
        return f"<lgvi.Result {name!r}: {bodies}, {len(self)} steps written, t in [0, {t_end:.6g}], {state}>"

    # Output ----------------------------------------------------------------
    def save(self, run_dir):
        """Write a run folder like the CLI's: trajectory.csv in the result's layout (17 significant digits,
        exact round trip), summary.json, if known scenario.toml, and the side tables it has (sensors.csv, the
        long layout's wheels.csv). `lgvi.load` and `python3 -m lgvi.plot` read it. Returns run_dir."""
        os.makedirs(run_dir, exist_ok=True)
        _save_table(os.path.join(run_dir, "trajectory.csv"), list(self.columns),
                    self.data.reshape(-1, self.data.shape[-1]))
        with open(os.path.join(run_dir, "summary.json"), "w", encoding="utf-8") as f:
            json.dump(self.summary, f, indent=2)
            f.write("\n")
        if self.scenario_toml is not None:
            with open(os.path.join(run_dir, "scenario.toml"), "w", encoding="utf-8") as f:
                f.write(self.scenario_toml)
        for file, table in (("sensors.csv", self._sensors), ("wheels.csv", self._wheel_rows)):
            if table:
                names = list(table)
                _save_table(os.path.join(run_dir, file), names, np.column_stack([table[n] for n in names]))
        return run_dir

    def draw_figures(self, out_dir):
        """Deprecated: use ``lgvi.plot.draw_figures(result, out_dir)`` (the same figures; returns the paths)."""
        return _deprecated_draw_figures(self, out_dir)


def _save_table(path, names, rows):
    np.savetxt(path, rows, fmt="%.17g", delimiter=",", header=",".join(names), comments="")


class _LongLayoutResult(type):
    """SystemResult's metaclass: isinstance(r, SystemResult) is what it was, a result of many bodies (the
    long layout), for code written before Result took both layouts."""

    def __instancecheck__(cls, obj):
        return isinstance(obj, Result) and obj.layout == "long"


class SystemResult(Result, metaclass=_LongLayoutResult):
    """Deprecated: lgvi.Result holds a many-body run too (``layout`` "long", arrays with a body axis).
    ``SystemResult(data, ...)`` is ``Result(data, ..., layout="long")`` with a DeprecationWarning."""

    def __init__(self, data, summary=None, scenario_toml=None, source=None, columns=None, names=None):
        warnings.warn("lgvi.SystemResult is deprecated: lgvi.Result holds many-body runs too (layout \"long\"); "
                      "use Result(data, summary, ..., layout=\"long\")", DeprecationWarning, stacklevel=2)
        super().__init__(data, summary, scenario_toml, source, columns, names, layout="long")


def _deprecated_draw_figures(result, out_dir):
    """Result.draw_figures, kept working for code that calls it.

    The data layer does not depend on the figure layer (lgvi.plot imports this module, not the
    reverse): this shim is the one upward import left in the package, named as such in
    tests/python/test_import_layers.py, and goes when the method goes."""
    warnings.warn(f"{type(result).__name__}.draw_figures is deprecated: call lgvi.plot.draw_figures(result, "
                  f"out_dir) (the same figures)", DeprecationWarning, stacklevel=3)
    from . import plot  # deprecated upward import (see the docstring)
    return plot.draw_figures(result, out_dir)
