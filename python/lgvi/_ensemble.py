"""Ensembles from Python: the sweep of `lgvi ensemble` on any concurrent.futures.Executor.

The plan (members, draws, up-front checks) and each member's run are the CLI's compiled code
(lgvi._core), so the rows are the bytes of the CLI's members.csv whatever executor runs them:
a ProcessPoolExecutor, mpi4py.futures.MPIPoolExecutor, or a Dask cluster's
``distributed.Client.get_executor()``.
"""

import csv
import io
import os

import numpy as np

from . import _check  # _core is imported where a member runs: plotting works from the source tree
from ._toml import toml_text as _toml_text  # the CLI's TOML writer


def _sweep_text(scenario_name, vary, members, seed, trajectories, metrics=None, settle_band_deg=None,
                sensor_noise=None):
    ensemble = {"scenario": scenario_name + ".toml"}
    if sensor_noise is not None:
        ensemble["sensor_noise"] = str(sensor_noise)
    if metrics is not None:
        if isinstance(metrics, str):
            metrics = [metrics]
        ensemble["metrics"] = [str(m) for m in metrics]
    if settle_band_deg is not None:
        ensemble["settle_band_deg"] = float(settle_band_deg)
    if members is not None:
        ensemble["members"] = _check.integer(members, "members", 1)
    if seed is not None:
        ensemble["seed"] = _check.integer(seed, "seed", 0)
    if trajectories != "none":
        raise ValueError("trajectories: lgvi.ensemble returns the members table only; keep every member's run "
                         "folder with the CLI (lgvi ensemble, [ensemble] trajectories = \"all\")")
    if isinstance(vary, dict):
        vary = [vary]
    if isinstance(vary, (str, bytes)) or not hasattr(vary, "__iter__"):
        raise ValueError(f"vary: must be a list of dicts like {{'key': 'initial.omega', 'normal': {{'mean': [..], "
                         f"'std': [..]}}}}, got {vary!r}")
    for i, v in enumerate(vary):
        if not isinstance(v, dict):
            raise ValueError(f"vary[{i}]: must be a dict with key and one of normal, uniform, values, rotation")
    return _toml_text({"ensemble": ensemble, "vary": [_plain(v) for v in vary]})


def _plain(x):
    """numpy arrays and scalars as lists and floats (TOML values), in lists and dicts too."""
    if isinstance(x, np.ndarray):
        return _plain(x.tolist())
    if isinstance(x, (list, tuple)):
        return [_plain(v) for v in x]
    if isinstance(x, dict):
        return {k: _plain(v) for k, v in x.items()}
    if isinstance(x, np.generic):
        return x.item()
    return x


def _run_member(args):
    """One member in a worker process: (index, varied, scenario TOML, scenario name, metrics, settle band)
    -> its row."""
    from . import _core as core  # a fresh worker imports the compiled module here
    return core.run_member(*args)


class EnsembleResult:
    """The members table of an ensemble (the CLI's members.csv).

    ``text`` is members.csv's content, byte for byte the CLI's; ``header`` its column names;
    ``columns`` maps each name to a numpy array (one entry per member, in member order), except
    ``error``, a list of str ("" for members that completed). ``completed`` is a bool array.
    ``changes_not_errors``: the "..._error" columns that measure the change of a quantity the
    members' dynamics does not conserve (a forcing or an external field), not an error of the method.
    With pointing metrics ([ensemble] metrics): ``pointing_times`` (F,) and ``pointing_error``
    (members, F), each member's pointing error in degrees at the base scenario's output frames (the
    CLI's pointing_error.csv; NaN after a failure), and ``settle_band_deg``; otherwise None.
    """

    def __init__(self, text, changes_not_errors=(), pointing_times=None, pointing_error=None, settle_band_deg=None):
        self.text = text
        self.changes_not_errors = tuple(changes_not_errors)
        self.pointing_times = None if pointing_times is None else np.asarray(pointing_times, dtype=float)
        self.pointing_error = None if pointing_error is None else np.asarray(pointing_error, dtype=float)
        self.settle_band_deg = settle_band_deg
        reader = csv.reader(io.StringIO(text))
        self.header = next(reader)
        rows = list(reader)
        self.columns = {}
        for j, name in enumerate(self.header):
            values = [r[j] for r in rows]
            self.columns[name] = values if name == "error" else np.array([float(v) for v in values])
        self.completed = self.columns["completed"].astype(bool) if rows else np.zeros(0, bool)

    def __len__(self):
        return len(self.completed)

    def __getitem__(self, name):
        return self.columns[name]

    def save(self, path):
        """Write members.csv."""
        with open(os.fspath(path), "w", newline="") as f:
            f.write(self.text)

    def __repr__(self):
        return f"<lgvi.EnsembleResult: {len(self)} members, {int((~self.completed).sum())} failed>"


def ensemble(scenario, vary, members=None, seed=None, executor=None, trajectories="none", metrics=None,
             settle_band_deg=None, sensor_noise=None):
    """Run an ensemble of a scenario with some of its numbers varied; returns an lgvi.EnsembleResult.

    The semantics of ``lgvi ensemble`` (docs/guide/ensembles.md): ``vary`` is a list of dicts, each
    with ``key`` (a dotted scenario key: "initial.omega", "integrator.step",
    "bodies.NAME.omega") and one of ``normal={"mean": .., "std": ..}``, ``uniform={"low": ..,
    "high": ..}``, ``rotation="uniform"`` (random attitudes; with ``members`` and ``seed``), or
    ``values=[...]`` (a grid; the ensemble is the product of the grids), or, for a quaternion
    key, ``attitude_error_deg=SIGMA`` (errors about random axes by angles of SIGMA degrees rms). A
    key may name an element: "body.inertia[0][0]". ``metrics`` and ``settle_band_deg``: the GNC
    columns of ``[ensemble] metrics`` (pointing_error_deg, settling_time, max_wheel_torque,
    max_wheel_speed, saturation_time, control_effort). ``sensor_noise``: "per-member" (default: each
    member's [[sensor]] seeds drawn from its index) or "shared" (the base's seeds in every member).
    Every member's scenario is checked before any runs (ValueError naming the member and the key).

    A Scenario read from a file holds its text with initial.orbit and initial.attitude converted to
    plain keys (position, momentum, quaternion, w or omega): an attitude error then composes with that
    quaternion and leaves the rate as it was, where ``lgvi ensemble`` on the file gives it to
    initial.attitude (whose rate = "orbit" turns with it); keys of orbit and attitude cannot be varied.

    ``executor``: any concurrent.futures.Executor (``ProcessPoolExecutor``,
    ``mpi4py.futures.MPIPoolExecutor``, ``distributed.Client(...).get_executor()``); None runs
    the members one after the other here. The result is the same for every executor: the rows
    are the CLI's members.csv bytes.
    """
    from ._api import _scenario
    sc = _scenario(scenario)
    plan = _plan(sc, vary, members, seed, trajectories, metrics, settle_band_deg, sensor_noise)
    band = plan.settle_band_deg
    work = [(i, plan.varied(i), plan.member_toml(i), plan.scenario_name, plan.metrics, band)
            for i in range(plan.members)]
    if executor is None:
        rows = [_run_member(w) for w in work]
    else:
        rows = list(executor.map(_run_member, work))
    parts = [plan.split_row(r) for r in rows]
    text = plan.header + "\n" + "".join(p[0] + "\n" for p in parts)
    if not plan.series_times:
        return EnsembleResult(text, plan.changes_not_errors)
    curves = np.array([[float(v) for v in p[1].split(",")] for p in parts]).reshape(len(parts), -1)
    return EnsembleResult(text, plan.changes_not_errors, plan.series_times, curves,
                          None if np.isnan(band) else band)


def _plan(sc, vary, members, seed, trajectories, metrics=None, settle_band_deg=None, sensor_noise=None):
    from . import _core
    text = _sweep_text(sc.name, vary, members, seed, trajectories, metrics, settle_band_deg, sensor_noise)
    try:
        return _core.ensemble_plan(text, "ensemble", sc.toml)
    except ValueError as e:
        raise ValueError(str(e)) from None
