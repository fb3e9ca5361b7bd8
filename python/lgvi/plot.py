"""The paper's figures for one lgvi run: ``python3 -m lgvi.plot RUN_DIR [--out OUT_DIR]``.

Draws trajectory.png, body_motion.png, energy_error.png, quaternion_error.png
and momentum_error.png from a trajectory on disk (a run folder of the CLI,
with trajectory.csv, trajectory.npz or trajectory.h5 and summary.json) or in
memory (an ``lgvi.Result`` from ``lgvi.simulate``): ``draw_figures(source,
out_dir)``. The CLI (``lgvi run``) draws its figures through this same code,
so there is one plotting path. Quaternions are scalar-first (qw, qx, qy, qz).
Needs numpy and matplotlib only (not the compiled lgvi._core).
"""

import argparse
import json
import os
import sys
import warnings

import numpy as np

from ._attitude import euler_angles, lvlh_angles, rotation_matrices
from ._columns import body_of
from ._io import _trajectory_in, load, load_run  # noqa: F401 (load_run: lgvi.plot.load_run, as before)
from ._result import Result

REQUIRED_COLUMNS = ("t", "x", "y", "qw", "qx", "qy", "qz", "energy_error",
                    "quat_norm_error", "Lx", "Ly", "Lz", "momentum_error")
DPI = 120
FIGSIZE = (6.0, 4.5)
N_INSTANTS = 12
#: body_motion.png draws the attitude against time instead of the body on its
#: path when the body's size is below this fraction of the path's extent (a
#: 1 m satellite on a 6.9e6 m orbit would be a dot).
TINY_BODY = 1e-3


def _pyplot():
    """Import matplotlib lazily, with the non-interactive Agg backend."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    return plt


def rotation_matrix(q):
    """Rotation matrix R = pi(q) of a scalar-first unit quaternion q = (qw, qx, qy, qz).

    Shape (4,) -> (3, 3) or (..., 4) -> (..., 3, 3); the one implementation,
    lgvi's attitude helpers' (``Result.rotation_matrices``).
    """
    return rotation_matrices(q)


def orbit_period(t, x, y):
    """Time for the polar angle of (x, y) to first turn by 2*pi, or None.

    The angle is unwrapped; the crossing is linearly interpolated between rows.
    Returns None when the run never completes a revolution.
    """
    t, x, y = (np.asarray(a, dtype=float) for a in (t, x, y))
    if t.size < 2:
        return None
    angle = np.unwrap(np.arctan2(y, x))
    turned = np.abs(angle - angle[0])
    hits = np.flatnonzero(turned >= 2.0 * np.pi)
    if hits.size == 0 or hits[0] == 0:
        return None
    i = hits[0]
    frac = (2.0 * np.pi - turned[i - 1]) / (turned[i] - turned[i - 1])
    return float(t[i - 1] + frac * (t[i] - t[i - 1]) - t[0])


def _save(fig, out_dir, name, written):
    path = os.path.join(out_dir, name)
    fig.tight_layout()
    fig.savefig(path, dpi=DPI)
    _pyplot().close(fig)
    written.append(path)


def _outside_legend(ax):
    """Legend to the right of the axes, so it never hides the orbit or the origin."""
    ax.legend(loc="upper left", bbox_to_anchor=(1.02, 1.0), borderaxespad=0.0, fontsize="small")


def _trajectory(plt, c, out_dir, written):
    fig, ax = plt.subplots(figsize=FIGSIZE)
    ax.plot(c["x"], c["y"], lw=1.0, label="centre of mass")
    ax.plot(c["x"][0], c["y"][0], "o", color="tab:green", label="start")
    ax.plot(0.0, 0.0, "*", color="black", ms=12, label="origin\n(attracting centre)")
    ax.set_aspect("equal", adjustable="datalim")
    ax.set(title="Centre-of-mass trajectory (x-y projection)", xlabel="x", ylabel="y")
    _outside_legend(ax)
    _save(fig, out_dir, "trajectory.png", written)


def _body_size(summary):
    """The body's radius: its farthest ball's reach, else sqrt(trace J / m) (0 if unknown)."""
    body = body_of(summary)
    balls = body.get("balls") or []
    if balls:
        return max(np.linalg.norm(b["position"]) + b.get("radius", 0.0) for b in balls)
    inertia, mass = body.get("inertia"), body.get("mass")
    if inertia is None or not mass:
        return 0.0
    return float(np.sqrt(np.trace(np.asarray(inertia, dtype=float)) / mass))


def _attitude_against_time(plt, c, extent, size, out_dir, written):
    """body_motion.png for a body tiny against its path: its attitude in the LVLH
    frame of its orbit about the origin (roll, pitch, yaw against time), or in
    the inertial axes when it has no orbit about the origin."""
    t = c["t"]
    x = np.column_stack([c["x"], c["y"], c["z"]])
    p = np.column_stack([c["px"], c["py"], c["pz"]])
    q = np.column_stack([c["qw"], c["qx"], c["qy"], c["qz"]])
    try:
        angles = lvlh_angles(x, p, q)
        names = ("roll (about along-track y)", "pitch (about orbit normal z)", "yaw (about radial x)")
        frame = "LVLH frame (x radial, y along-track, z orbit normal)"
    except ValueError:
        angles = euler_angles(rotation_matrices(q), "ZYX", degrees=True)[:, ::-1]
        names = ("about x (last)", "about y", "about z (first)")
        frame = "inertial axes, intrinsic z-y-x"
    # The first three orbits (as the path figure draws one), else the whole run.
    period = orbit_period(t, c["x"], c["y"])
    shown = np.ones(len(t), dtype=bool) if period is None else t <= t[0] + 3.0 * period
    span = "whole run" if period is None or shown.all() else f"first 3 orbits (T = {period:.6g})"
    fig, ax = plt.subplots(figsize=(8.0, 4.5))
    for k, name in enumerate(names):
        ax.plot(t[shown], angles[shown, k], lw=1.0, label=name)
    ax.set(title=f"Attitude in the {frame}, {span}\n(body size {size:.3g} vs path {extent:.3g}: "
                 "too small to draw on the path)", xlabel="t", ylabel="angle (deg)")
    ax.title.set_fontsize("small")
    _outside_legend(ax)
    _save(fig, out_dir, "body_motion.png", written)


def _body_motion(plt, c, summary, out_dir, written):
    t, x, y = c["t"], c["x"], c["y"]
    path_extent = max(np.ptp(x), np.ptp(y), np.ptp(c["z"]) if "z" in c else 0.0)
    size = _body_size(summary)
    if size > 0.0 and size < TINY_BODY * path_extent and all(k in c for k in ("z", "px", "py", "pz")):
        _attitude_against_time(plt, c, path_extent, size, out_dir, written)
        return
    period = orbit_period(t, x, y)
    if period is None:
        idx = np.linspace(0, len(t) - 1, N_INSTANTS)
        title = "Body motion, whole run"
    else:
        i_end = int(np.searchsorted(t, t[0] + period))
        idx = np.linspace(0, min(i_end, len(t) - 1), N_INSTANTS, endpoint=False)
        title = f"Body motion, one orbit (period T = {period:.6g})"
    idx = np.unique(np.round(idx).astype(int))
    balls = body_of(summary).get("balls") or []
    rho = np.array([b["position"] for b in balls], dtype=float).reshape(-1, 3)
    radii = np.array([b.get("radius", 0.0) for b in balls], dtype=float)
    quats = np.column_stack([c["qw"], c["qx"], c["qy"], c["qz"]])
    com = np.column_stack([x, y, c["z"] if "z" in c else np.zeros_like(x)])
    extent = max(np.ptp(x), np.ptp(y), 1e-12)
    colors = plt.get_cmap("viridis")(np.linspace(0.0, 1.0, len(idx)))

    fig, ax = plt.subplots(figsize=FIGSIZE)
    ax.plot(x, y, color="0.75", lw=0.8, zorder=0, label="centre-of-mass path")
    for k, (i, col) in enumerate(zip(idx, colors)):
        R = rotation_matrix(quats[i])
        if len(rho) == 0:
            axis = com[i] + 0.05 * extent * R[:, 0]
            ax.plot([com[i, 0], axis[0]], [com[i, 1], axis[1]], color=col, lw=1.5)
            ax.plot(com[i, 0], com[i, 1], "o", color=col, ms=4)
            continue
        pos = com[i] + rho @ R.T  # x + R rho_i for every ball
        for a in range(len(pos)):
            for b in range(a + 1, len(pos)):
                ax.plot(pos[[a, b], 0], pos[[a, b], 1], color=col, lw=1.0)
        for p, r in zip(pos, radii):
            if r > 0.0:
                ax.add_patch(plt.Circle((p[0], p[1]), r, color=col, alpha=0.35))
        ax.plot(pos[:, 0], pos[:, 1], "o", color=col, ms=4,
                label=f"t = {t[i]:.4g}" if k in (0, len(idx) - 1) else None)
    ax.plot(0.0, 0.0, "*", color="black", ms=10, label="origin")
    ax.set_aspect("equal", adjustable="datalim")
    ax.set(title=title, xlabel="x", ylabel="y")
    _outside_legend(ax)
    _save(fig, out_dir, "body_motion.png", written)


def _error_plot(plt, t, values, ylabel, title, name, out_dir, written, scale=None):
    """Linear plot of a signed error with scientific offset notation."""
    fig, ax = plt.subplots(figsize=FIGSIZE)
    ax.plot(t, values, lw=0.8)
    ax.ticklabel_format(axis="y", style="sci", scilimits=(0, 0), useOffset=True)
    ax.set(title=title, xlabel="t", ylabel=ylabel)
    if scale:  # second axis: the same curve divided by `scale`
        sec = ax.secondary_yaxis("right", functions=(lambda v: v / scale, lambda v: v * scale))
        sec.ticklabel_format(axis="y", style="sci", scilimits=(0, 0), useOffset=True)
        sec.set_ylabel(ylabel + " / |L(0)|")
    _save(fig, out_dir, name, written)


def _max_abs(values):
    return float(np.max(np.abs(values)))


def _step_size(plt, t, energy_error, summary, out_dir, written):
    """step_size.png for an adaptive run ([integrator] time_transform): the
    physical step against t (the mean over each interval between written
    rows, output_every steps; the last interval may hold fewer) above |E - E0|,
    on log scales, so that the close passes show as dips of both. Nothing for
    a fixed step."""
    setup = (summary or {}).get("setup", {})
    if setup.get("integrator", {}).get("time_transform") is None or len(t) < 3:
        return
    every = setup.get("output_every", 1)
    fig, (top, bottom) = plt.subplots(2, 1, sharex=True, figsize=(FIGSIZE[0], FIGSIZE[1] * 1.4))
    top.semilogy(t[1:-1], np.diff(t[:-1]) / every, lw=0.8)
    top.set(ylabel="step dt", title=f"Adaptive step (epsilon = {setup['integrator']['epsilon']:g}; "
            f"dt in [{summary['min_step']:.2e}, {summary['max_step']:.2e}])")
    bottom.semilogy(t, np.maximum(np.abs(energy_error), 1e-18), lw=0.8)
    bottom.set(xlabel="t", ylabel="|E - E0| (floor 1e-18)")
    _save(fig, out_dir, "step_size.png", written)


def _columns_and_summary(source):
    """(columns, summary, scenario TOML text or None, default out_dir) of a run folder/trajectory file or an
    in-memory result."""
    if isinstance(source, (str, bytes, os.PathLike)):
        path = os.fsdecode(source)
        if os.path.isdir(path):
            columns, summary = load_run(path)
            toml_path = os.path.join(path, "scenario.toml")
            scenario = None
            if os.path.isfile(toml_path):
                with open(toml_path, encoding="utf-8") as f:
                    scenario = f.read()
            return columns, summary, scenario, path
        result = load(path)
        return result.columns, result.summary, result.scenario_toml, os.path.dirname(path) or "."
    columns = getattr(source, "columns", None)
    summary = getattr(source, "summary", None)
    if not isinstance(columns, dict) or not isinstance(summary, dict):
        raise TypeError("draw_figures: source must be a run folder, a trajectory file or an lgvi.Result "
                        f"(with .columns and .summary), got {type(source).__name__}")
    return columns, summary, getattr(source, "scenario_toml", None), None


def _system_result(source):
    """The Result of a run folder/file or object in the long layout (one row a step and body: a many-body
    run's), else None."""
    if isinstance(source, Result):
        return source if source.layout == "long" else None
    if isinstance(source, (str, bytes, os.PathLike)):
        path = os.fsdecode(source)
        file = path
        if os.path.isdir(path):
            file = _trajectory_in(path)
        if file.endswith(".csv"):
            with open(file, encoding="utf-8") as f:
                if not f.readline().startswith("t,body,"):
                    return None
        result = load(path)
        return result if result.layout == "long" else None
    return None


MAX_PATHS = 50  # bodies whose paths are drawn (a gas of thousands would be a blot)


def _momentum_words(summary):
    """("error" or "change") for the angular and for the linear momentum: a change where the
    run's dynamics does not conserve the quantity (summary["conserved"]["changes_not_errors"]: a
    forcing or an external field), so that a figure does not call it an error of the method."""
    changes = (summary or {}).get("conserved", {}).get("changes_not_errors", [])
    angular = "change" if "max_momentum_error" in changes else "error"
    linear = "change" if "max_linear_momentum_error" in changes else "error"
    return angular, linear


def _draw_thermodynamics(plt, r, out_dir, written):
    """thermodynamics.png of a molecular run: the kinetic temperature and, in a periodic box, the pressure of
    the rigid molecules at each written step, with their means over the written steps (the summary's)."""
    thermo = (r.summary or {}).get("thermodynamics", {})
    panels = [("temperature", "temperature (k_B = 1)")]
    if "pressure" in r.columns:
        panels.append(("pressure", "pressure (2 K_trans + W) / 3V"))
    fig, axes = plt.subplots(len(panels), 1, figsize=(FIGSIZE[0], FIGSIZE[1] * (0.6 + 0.4 * len(panels))),
                             sharex=True, squeeze=False)
    for ax, (name, label) in zip(axes[:, 0], panels):
        values = r.columns[name]
        mean = float(np.mean(values))
        ax.plot(r.t, values, lw=0.9)
        ax.axhline(mean, color="0.5", lw=0.8, ls="--", label=f"mean {mean:.4g}")
        ax.set_ylabel(label)
        ax.legend(loc="best", fontsize="small")
    axes[-1, 0].set_xlabel("t")
    dof = thermo.get("degrees_of_freedom")
    axes[0, 0].set_title(f"Temperature{' and pressure' if len(panels) > 1 else ''} of {r.bodies} rigid bodies"
                         + (f"\n({dof} degrees of freedom)" if dof else ""), fontsize="medium")
    _save(fig, out_dir, "thermodynamics.png", written)


def _draw_system(plt, r, out_dir, written):
    """The figures of a many-body run: the system's energy and momentum errors,
    the bodies' |q| - 1, their paths (projected), and for two bodies the
    secondary's libration about the line of centres."""
    t = r.t
    _error_plot(plt, t, r.energy_error, "energy error",
                f"System energy error (max |.| = {_max_abs(r.energy_error):.3e})", "energy_error.png",
                out_dir, written)
    _step_size(plt, t, r.energy_error, r.summary, out_dir, written)
    _error_plot(plt, t, np.max(np.abs(r.quat_norm_error), axis=1), "max over bodies of ||q| - 1|",
                f"Quaternion norm error, {r.bodies} bodies (max = {_max_abs(r.quat_norm_error):.3e})",
                "quaternion_error.png", out_dir, written)
    scale = np.sum(np.linalg.norm(np.cross(r.x[0], r.p[0]), axis=1) + 0.5 * np.linalg.norm(r.w[0], axis=1))
    fig, ax = plt.subplots(figsize=FIGSIZE)
    rel = r.momentum_error / scale if scale > 0 else r.momentum_error
    ax.semilogy(t, np.maximum(rel, 1e-18), label="|L - L0| / sum |x x p| + |w|/2")
    ax.semilogy(t, np.maximum(r.linear_momentum_error, 1e-18), label="|P - P0| / sum |p_a0|")
    ax.set_xlabel("t")
    angular, linear = _momentum_words(r.summary)
    ax.set_ylabel(f"relative {angular} / {linear} (floor 1e-18)" if angular != linear else
                  f"relative {angular} (floor 1e-18)")
    notes = ", ".join(f"{n} momentum: a change, not conserved here"
                      for n, w in (("angular", angular), ("linear", linear)) if w == "change")
    ax.set_title(f"Total angular and linear momentum (max {_max_abs(rel):.2e}, {_max_abs(r.linear_momentum_error):.2e})"
                 + (f"\n{notes}" if notes else ""))
    ax.legend(loc="best", fontsize="small")
    _save(fig, out_dir, "momentum_error.png", written)
    if "temperature" in r.columns:
        _draw_thermodynamics(plt, r, out_dir, written)
    fig, ax = plt.subplots(figsize=FIGSIZE)
    shown = np.unique(np.linspace(0, r.bodies - 1, min(r.bodies, MAX_PATHS)).astype(int))
    for a in shown:
        ax.plot(r.x[:, a, 0], r.x[:, a, 1], lw=0.8, label=r.names[a] if len(shown) <= 8 else None)
        ax.plot(r.x[-1, a, 0], r.x[-1, a, 1], "o", ms=3, color=ax.lines[-1].get_color())
    ax.set_aspect("equal", adjustable="datalim")
    ax.set_xlabel("x")
    ax.set_ylabel("y")
    more = "" if len(shown) == r.bodies else f" ({len(shown)} of {r.bodies} bodies)"
    ax.set_title("Paths of the centres of mass, projected on x-y" + more)
    if len(shown) <= 8:
        ax.legend(loc="best", fontsize="small")
    _save(fig, out_dir, "trajectory.png", written)
    if r.bodies == 2:
        # The angle between the secondary's body x-axis and the direction to
        # the primary, both projected on the plane normal to the relative
        # orbit's angular momentum: its libration about the synchronous state.
        rel_x = r.x[:, 0] - r.x[:, 1]
        rel_v = r.p[:, 0] / 1.0 - r.p[:, 1] / 1.0
        normal = np.cross(rel_x[0], rel_v[0])
        normal = normal / np.linalg.norm(normal) if np.linalg.norm(normal) > 0 else np.array([0.0, 0.0, 1.0])
        axis = np.array([rotation_matrix(q)[:, 0] for q in r.q[:, 1]])
        e1 = rel_x / np.linalg.norm(rel_x, axis=1)[:, None]
        e2 = np.cross(normal, e1)
        angle = np.degrees(np.arctan2(np.sum(axis * e2, axis=1), np.sum(axis * e1, axis=1)))
        # An axis, not a direction: +-x are the same line (a dumbbell's two ends).
        angle = (angle + 90.0) % 180.0 - 90.0
        fig, ax = plt.subplots(figsize=FIGSIZE)
        ax.plot(t, angle, lw=0.8)
        ax.set_xlabel("t")
        ax.set_ylabel("angle of the x-axis to the line of centres (degrees)")
        ax.set_title(f"Libration of {r.names[1]}: its x-axis against the line to {r.names[0]}")
        _save(fig, out_dir, "libration.png", written)
    return written


def _ensemble_table(source):
    """An ensemble's members table (lgvi.EnsembleResult, or a folder/file members.csv); None otherwise."""
    if hasattr(source, "header") and hasattr(source, "completed") and hasattr(source, "columns"):
        return source
    if isinstance(source, (str, bytes, os.PathLike)):
        path = os.fsdecode(source)
        csv_path = os.path.join(path, "members.csv") if os.path.isdir(path) else path
        if os.path.basename(csv_path) == "members.csv" and os.path.exists(csv_path):
            from ._ensemble import EnsembleResult
            with open(csv_path, newline="") as f:
                text = f.read()
            # Which columns are changes, not errors: lgvi ensemble's changes_not_errors.json beside
            # it (a members.csv alone does not say: its columns are then labelled by name).
            changes = ()
            marks = os.path.join(os.path.dirname(csv_path) or ".", "changes_not_errors.json")
            if os.path.exists(marks):
                with open(marks, encoding="utf-8") as f:
                    changes = json.load(f)
            return EnsembleResult(text, changes, *_pointing_curves(os.path.dirname(csv_path) or "."))
    return None


def _pointing_curves(folder):
    """An ensemble folder's pointing-error curves (pointing_error.csv: index, t, degrees, member by member)
    as (times, members x frames) and the sweep's settle_band_deg; Nones where absent."""
    path = os.path.join(folder, "pointing_error.csv")
    if not os.path.exists(path):
        return None, None, None
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # no member finished yet: the header alone
        data = np.loadtxt(path, delimiter=",", skiprows=1, ndmin=2).reshape(-1, 3)
    if len(data) == 0:
        return None, None, None
    index = data[:, 0].astype(np.int64)
    members = np.unique(index)
    frames = len(data) // max(1, len(members))
    times = data[:frames, 1]
    curves = data[:, 2].reshape(len(members), frames)
    band = None
    sweep = os.path.join(folder, "sweep.toml")
    if os.path.exists(sweep):
        import tomllib
        with open(sweep, "rb") as f:
            band = tomllib.load(f).get("ensemble", {}).get("settle_band_deg")
    return times, curves, band


_ENSEMBLE_ERRORS = (("max_abs_energy_error", "max |E - E0|"), ("max_abs_quat_norm_error", "max ||q| - 1|"),
                    ("max_momentum_error", "max |L - L0|"))


def _draw_ensemble(plt, e, out_dir, written):
    """error_distribution.png: each error's histogram over the completed members (log scale), a
    quantity the members do not conserve labelled as a change; error_vs_varied.png: the energy
    error against each varied value."""
    ok = e.completed
    fig, axes = plt.subplots(1, 3, figsize=(13, 3.8))
    for ax, (name, label) in zip(axes, _ENSEMBLE_ERRORS):
        if name in getattr(e, "changes_not_errors", ()):
            label += " (a change: not conserved here)"
        v = np.asarray(e.columns[name])[ok]
        v = v[np.isfinite(v)]
        floor = np.finfo(float).tiny
        logs = np.log10(np.maximum(v, floor)) if len(v) else v
        ax.hist(logs, bins=min(40, max(5, len(v) // 4 or 5)), color="tab:blue", alpha=0.8)
        ax.set_xlabel(f"log10 {label}")
        ax.set_ylabel("members")
        ax.set_title(f"{label}: median {np.median(v):.2e}" if len(v) else label)
    fig.suptitle(f"{len(e)} members, {int((~ok).sum())} failed")
    fig.tight_layout()
    _save(fig, out_dir, "error_distribution.png", written)
    varied = e.header[1:e.header.index("completed")]
    if varied:
        # Every varied value (a vector key varies each component), four panels a row; past 24 the
        # figure would be unreadable: the first 24, and the title says so.
        shown = varied[:24]
        ncols = min(4, len(shown))
        nrows = (len(shown) + ncols - 1) // ncols
        fig, axes = plt.subplots(nrows, ncols, figsize=(3.6 * ncols, 3.2 * nrows), squeeze=False)
        for ax in axes.flat[len(shown):]:
            ax.set_visible(False)
        if len(shown) < len(varied):
            fig.suptitle(f"the first {len(shown)} of {len(varied)} varied values", fontsize=9)
        energy = np.asarray(e.columns["max_abs_energy_error"])
        for ax, name in zip(axes.flat, shown):
            x = np.asarray(e.columns[name])
            ax.semilogy(x[ok], np.maximum(energy[ok], np.finfo(float).tiny), ".", ms=4, label="completed")
            if (~ok).any():
                ax.plot(x[~ok], np.full((~ok).sum(), np.nanmax(energy[ok]) if ok.any() else 1.0), "x",
                        color="tab:red", label="failed")
                ax.legend(fontsize=7)
            ax.set_xlabel(name)
            ax.set_ylabel("max |E - E0|")
        fig.tight_layout()
        _save(fig, out_dir, "error_vs_varied.png", written)
    _draw_gnc(plt, e, out_dir, written)
    return written


_METRIC_LABELS = {"pointing_error_deg": "final pointing error (deg)", "settling_time": "settling time (s)",
                  "max_wheel_torque": "largest wheel torque (N m)", "max_wheel_speed": "largest wheel speed (rad/s)",
                  "saturation_time": "time at a wheel limit (s)", "control_effort": "control effort (N m s)"}


def _draw_gnc(plt, e, out_dir, written):
    """With [ensemble] metrics: pointing_error.png (every member's pointing error against time, one faint
    line each, with the settling band) and metrics.png (each metric's histogram over the members; members
    that never settled counted in the title)."""
    curves = getattr(e, "pointing_error", None)
    if curves is not None and len(curves):
        t = e.pointing_times
        band = getattr(e, "settle_band_deg", None)
        fig, ax = plt.subplots(figsize=(8, 4.5))
        floor = np.finfo(float).tiny
        for row in curves:
            ax.semilogy(t, np.maximum(row, floor), color="tab:blue", alpha=min(0.6, max(0.05, 8.0 / len(curves))),
                        lw=0.8)
        if band is not None:
            ax.axhline(band, color="tab:red", ls="--", lw=1.2, label=f"settling band {band:g} deg")
            ax.legend(loc="upper right")
        ax.set_xlabel("t")
        ax.set_ylabel("pointing error (deg)")
        ax.set_title(f"Pointing error of {len(curves)} members")
        fig.tight_layout()
        _save(fig, out_dir, "pointing_error.png", written)
    shown = [m for m in _METRIC_LABELS if m in e.columns]
    if not shown:
        return
    ncols = min(3, len(shown))
    nrows = (len(shown) + ncols - 1) // ncols
    fig, axes = plt.subplots(nrows, ncols, figsize=(4.2 * ncols, 3.4 * nrows), squeeze=False)
    for ax in axes.flat[len(shown):]:
        ax.set_visible(False)
    for ax, name in zip(axes.flat, shown):
        v = np.asarray(e.columns[name])[e.completed]
        finite = v[np.isfinite(v)]
        # One value for every member (a limit reached by all): a bar around it, not an empty range.
        spread = None if len(finite) == 0 or finite.min() < finite.max() else \
            (finite[0] - 0.05 * abs(finite[0]) - 1e-12, finite[0] + 0.05 * abs(finite[0]) + 1e-12)
        ax.hist(finite, bins=min(40, max(5, len(finite) // 5 or 5)), range=spread, color="tab:blue", alpha=0.8)
        ax.set_xlabel(_METRIC_LABELS[name])
        ax.set_ylabel("members")
        title = f"median {np.median(finite):.3g}, max {finite.max():.3g}" if len(finite) else "none"
        if len(finite) < len(v):
            title += f"; {len(v) - len(finite)} not settled" if name == "settling_time" else \
                f"; {len(v) - len(finite)} NaN"
        ax.set_title(title, fontsize=9)
    fig.suptitle(f"{len(e)} members, {int((~e.completed).sum())} failed")
    fig.tight_layout()
    _save(fig, out_dir, "metrics.png", written)


def _out_dir_of(source, out_dir):
    """out_dir, or the folder of a source given by path (required for an in-memory result)."""
    if out_dir is not None:
        return out_dir
    if not isinstance(source, (str, bytes, os.PathLike)):
        raise ValueError("out_dir: required when drawing an in-memory result")
    path = os.fsdecode(source)
    return path if os.path.isdir(path) else (os.path.dirname(path) or ".")


def draw_figures(source, out_dir=None):
    """Draw the paper's five PNG figures of a run into out_dir.

    body_motion.png draws the body on its path; when the body is smaller than
    TINY_BODY (1e-3) times the path's extent, it draws the attitude against
    time instead: roll, pitch, yaw in the LVLH frame of the orbit about the
    origin (as Result.lvlh_angles), or z-y-x Euler angles in the inertial
    axes when there is no orbit about the origin.

    ``source`` is a run folder (trajectory.csv, .npz or .h5 plus
    summary.json), a trajectory file, or an in-memory ``lgvi.Result`` (any
    object with ``.columns``, a dict of 1-D arrays named as in the CSV
    header, and ``.summary``, the summary dict). ``out_dir`` defaults to the
    run folder; it is required for an in-memory result. Quaternion columns
    are scalar-first (qw, qx, qy, qz). Returns the list of written paths.
    Raises OSError/ValueError on bad input. A trajectory in the long layout
    (a many-body run's: an lgvi.Result of layout "long", or its folder) gets its own
    figures: energy_error.png, quaternion_error.png, momentum_error.png (total
    angular and linear momentum), trajectory.png (the bodies' paths), for a molecular run
    thermodynamics.png (temperature, and pressure in a periodic box) and, for
    two bodies, libration.png. An adaptive run ([integrator] time_transform)
    also gets step_size.png (the step and |E - E0| against t). An ensemble (a folder with members.csv, or an
    lgvi.EnsembleResult) gets error_distribution.png and error_vs_varied.png.
    """
    ensemble = _ensemble_table(source)
    if ensemble is not None:
        out_dir = _out_dir_of(source, out_dir)
        os.makedirs(out_dir, exist_ok=True)
        return _draw_ensemble(_pyplot(), ensemble, out_dir, [])
    system = _system_result(source)
    if system is not None:
        out_dir = _out_dir_of(source, out_dir)
        if len(system) == 0:
            raise ValueError("draw_figures: the trajectory has no rows")
        os.makedirs(out_dir, exist_ok=True)
        return _draw_system(_pyplot(), system, out_dir, [])
    c, summary, scenario_text, default_out = _columns_and_summary(source)
    missing = [n for n in REQUIRED_COLUMNS if n not in c]
    if missing:
        raise ValueError(f"trajectory.csv: missing column(s) {', '.join(missing)}")
    if len(c["t"]) == 0:
        raise ValueError("draw_figures: the trajectory has no rows")
    if out_dir is None:
        if default_out is None:
            raise ValueError("out_dir: required when drawing an in-memory result")
        out_dir = default_out
    os.makedirs(out_dir, exist_ok=True)
    plt = _pyplot()
    written = []
    t = c["t"]
    _trajectory(plt, c, out_dir, written)
    _body_motion(plt, c, summary, out_dir, written)
    _error_plot(plt, t, c["energy_error"], "energy error",
                f"Energy error (max |.| = {_max_abs(c['energy_error']):.3e})",
                "energy_error.png", out_dir, written)
    _step_size(plt, t, c["energy_error"], summary, out_dir, written)
    _error_plot(plt, t, c["quat_norm_error"], "|q| - 1",
                f"Quaternion norm error (max |.| = {_max_abs(c['quat_norm_error']):.3e})",
                "quaternion_error.png", out_dir, written)
    l0 = float(np.linalg.norm([c["Lx"][0], c["Ly"][0], c["Lz"][0]]))
    err = c["momentum_error"]
    angular, _ = _momentum_words(summary)
    title = ("Momentum error" if angular == "error" else "Angular momentum change (not conserved here)") + \
        f" |L(t) - L(0)| (max = {_max_abs(err):.3e}"
    title += f", relative {_max_abs(err) / l0:.3e})" if l0 > 0.0 else ")"
    _error_plot(plt, t, err, "|L(t) - L(0)|", title, "momentum_error.png",
                out_dir, written, scale=l0 if l0 > 0.0 else None)
    _wheels(plt, c, summary, out_dir, written)
    _pointing_error(plt, c, scenario_text, out_dir, written)
    return written


def _pointing_error(plt, c, scenario_text, out_dir, written):
    """pointing_error.png for a body under one attitude controller ([[forcing]] kind = "attitude-control"):
    the angle between its attitude and the controller's target, 2 atan2(|Im e|, |Re e|) with e = target* q,
    against t (log scale), the final value in the title."""
    if scenario_text is None:
        return
    import tomllib
    controllers = [f for f in tomllib.loads(scenario_text).get("forcing", [])
                   if isinstance(f, dict) and f.get("kind") == "attitude-control" and "target" in f]
    if len(controllers) != 1:
        return
    target = np.asarray(controllers[0]["target"], dtype=float)
    target = target / np.linalg.norm(target)
    q = np.column_stack([c["qw"], c["qx"], c["qy"], c["qz"]])
    # e = target* q (Hamilton product, scalar first)
    w, v = target[0], target[1:]
    e_w = w * q[:, 0] + q[:, 1:] @ v
    e_v = w * q[:, 1:] - q[:, :1] * v - np.cross(v, q[:, 1:])
    degrees = np.degrees(2.0 * np.arctan2(np.linalg.norm(e_v, axis=1), np.abs(e_w)))
    fig, ax = plt.subplots(figsize=FIGSIZE)
    ax.plot(c["t"], degrees, lw=0.9)
    if np.all(degrees[1:] > 0.0):
        ax.set_yscale("log")
    ax.set(title=f"Pointing error (final {degrees[-1]:.3g} deg)", xlabel="t", ylabel="pointing error (deg)")
    ax.grid(True, which="both", lw=0.3)
    _save(fig, out_dir, "pointing_error.png", written)


def _wheels(plt, c, summary, out_dir, written):
    """wheels.png for a body with reaction wheels: each wheel's speed relative to the body, and the torque
    applied to it, against t (the limits dashed where the summary gives them)."""
    wheels = body_of(summary).get("wheels") or []
    if not wheels:
        return
    t = c["t"]
    fig, (top, bottom) = plt.subplots(2, 1, figsize=(FIGSIZE[0], FIGSIZE[1] * 1.4), sharex=True)
    for w in wheels:
        name = w["name"]
        line, = top.plot(t, c[f"{name}.speed"], lw=0.9, label=name)
        bottom.step(t, c[f"{name}.torque"], where="post", lw=0.9, color=line.get_color(), label=name)
        for ax, key in ((top, "max_speed"), (bottom, "max_torque")):
            if key in w:
                for sign in (1, -1):
                    ax.axhline(sign * w[key], color=line.get_color(), lw=0.6, ls="--")
    top.set_ylabel("speed relative to the body (rad/s)")
    top.set_title("Reaction wheels: speeds, and the torques applied (limits dashed)")
    bottom.set_ylabel("motor torque (N m)")
    bottom.set_xlabel("t")
    top.legend(loc="best", fontsize="small")
    _save(fig, out_dir, "wheels.png", written)


def main(argv=None):
    """Command-line entry: ``lgvi.plot RUN_DIR [--out OUT_DIR]``; returns the exit status.

    Quiet on success (0); on failure prints one ``lgvi.plot: error: ...`` line
    to stderr and returns 1.
    """
    parser = argparse.ArgumentParser(prog="lgvi.plot", description="Draw the figures of an lgvi run.")
    parser.add_argument("run_dir", help="run folder (trajectory.csv, .npz or .h5 and summary.json)")
    parser.add_argument("--out", dest="out_dir", default=None, help="output directory (default RUN_DIR)")
    args = parser.parse_args(argv)
    try:
        if not os.path.isdir(args.run_dir):
            raise OSError(f"run directory not found: {args.run_dir}")
        draw_figures(args.run_dir, args.out_dir)
    except KeyError as e:
        print(f"lgvi.plot: error: summary.json: missing key {e}", file=sys.stderr)
        return 1
    except (OSError, ValueError, TypeError) as e:
        msg = f"{e.strerror}: {e.filename}" if isinstance(e, OSError) and e.filename else str(e)
        print(f"lgvi.plot: error: {msg}", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
