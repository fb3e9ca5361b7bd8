"""Result: a trajectory with its diagnostics and summary, from lgvi.simulate()
or lgvi.load(). Pure numpy (no compiled code), so that lgvi.plot and
lgvi.load work from the source tree too."""

import json
import os

import numpy as np

#: The trajectory's columns, in the order of the CLI's trajectory.csv header.
COLUMNS = ("t", "x", "y", "z", "qw", "qx", "qy", "qz", "px", "py", "pz", "wx", "wy", "wz", "energy", "energy_error",
           "quat_norm_error", "Lx", "Ly", "Lz", "momentum_error")
HEADER = ",".join(COLUMNS)


class Result:
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
        if data.ndim != 2 or data.shape[1] != len(COLUMNS):
            raise ValueError(f"data: must have shape (N, {len(COLUMNS)}), got shape {data.shape}")
        #: The (N, 21) table.
        self.data = data
        #: Column name -> 1-D array (views into data), in the CSV header's order.
        self.columns = {name: data[:, i] for i, name in enumerate(COLUMNS)}
        #: The summary dict (the CLI's summary.json).
        self.summary = dict(summary or {})
        #: The scenario's TOML text, or None.
        self.scenario_toml = scenario_toml
        #: Where it was loaded from (a path), or None for a run in memory.
        self.source = source

    # Trajectory ------------------------------------------------------------
    @property
    def t(self):
        """Time t_k = k h of each row, shape (N,)."""
        return self.data[:, 0]

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
        """Body angular velocity Omega = J^-1 w / 2, shape (N, 3) (needs the body's inertia in the summary)."""
        inertia = _body(self.summary).get("inertia")
        if inertia is None:
            raise ValueError("omega: the summary has no body inertia (setup.body.inertia)")
        return 0.5 * np.linalg.solve(np.asarray(inertia, dtype=float), self.w.T).T

    # Summary ---------------------------------------------------------------
    @property
    def completed(self):
        """Whether every planned step was taken (summary["completed"])."""
        return bool(self.summary.get("completed", True))

    @property
    def error(self):
        """Why the run stopped early; "" if it completed."""
        return self.summary.get("error", "")

    def __len__(self):
        return self.data.shape[0]

    def __repr__(self):
        name = self.summary.get("scenario", "?")
        t_end = self.t[-1] if len(self) else float("nan")
        state = "completed" if self.completed else "NOT completed"
        return f"<lgvi.Result {name!r}: {len(self)} rows, t in [0, {t_end:.6g}], {state}>"

    # Output ----------------------------------------------------------------
    def save(self, run_dir):
        """Write a run folder like the CLI's: trajectory.csv (17 significant
        digits, exact round trip), summary.json and, if known, scenario.toml.
        `lgvi.load` and `python3 -m lgvi.plot` read it. Returns run_dir."""
        os.makedirs(run_dir, exist_ok=True)
        np.savetxt(os.path.join(run_dir, "trajectory.csv"), self.data, fmt="%.17g", delimiter=",", header=HEADER,
                   comments="")
        with open(os.path.join(run_dir, "summary.json"), "w", encoding="utf-8") as f:
            json.dump(self.summary, f, indent=2)
            f.write("\n")
        if self.scenario_toml is not None:
            with open(os.path.join(run_dir, "scenario.toml"), "w", encoding="utf-8") as f:
                f.write(self.scenario_toml)
        return run_dir

    def draw_figures(self, out_dir):
        """Draw the paper's five figures (PNG) into out_dir with lgvi.plot; returns the paths."""
        from . import plot
        return plot.draw_figures(self, out_dir)


def _body(summary):
    """The body of a summary: setup.body (the CLI's layout) or body."""
    if not isinstance(summary, dict):
        return {}
    body = summary.get("body")
    if body is None:
        body = (summary.get("setup") or {}).get("body")
    return body or {}
