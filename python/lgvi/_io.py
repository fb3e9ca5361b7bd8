"""Reading trajectories: a run folder of the CLI, or a trajectory file
(.csv, .npz, .h5). Pure numpy (h5py only for .h5), no compiled code.

Files (src/io/formats/csv.cpp, npz.cpp, hdf5.cpp; the columns: src/io/trajectory_sink.hpp), in either row
layout (the single-body layout's 21 columns and more, or the long layout's 26 and more, one row a step and
body; the header says which):

* trajectory.csv: the header line, then the rows with 17 significant
  digits; the summary and the scenario are the side files summary.json and
  scenario.toml of the run folder;
* trajectory.npz: entries trajectory.npy (float64, (rows, columns); the long
  layout's (steps, N, columns)), columns.npy (the names), scenario.npy and
  summary.npy (0-d unicode arrays: TOML and JSON text; written when the run
  closes the file);
* trajectory.h5: dataset /trajectory (float64, shaped as in npz) with
  attribute `columns`, root attributes `scenario` and `summary` (strings).
"""

import json
import os
import warnings
import zipfile

import numpy as np

from ._columns import bodies_columns, single_columns
from ._result import COLUMNS, Result

TRAJECTORY_FILES = ("trajectory.csv", "trajectory.npz", "trajectory.h5")


def _text(value):
    """A string from a numpy 0-d unicode array, bytes or str."""
    if isinstance(value, np.ndarray):
        value = value[()]
    if isinstance(value, bytes):
        value = value.decode("utf-8")
    return str(value)


def _check_columns(names, path):
    names = [_text(n).strip() for n in names]
    if single_columns(names) is None:
        raise ValueError(f"{path}: columns are {','.join(names)}; expected {','.join(COLUMNS)} (and work, "
                         f"for a forced scenario, and the reaction wheels' columns)")


def _read_side_file(folder, name):
    path = os.path.join(folder, name)
    if not os.path.isfile(path):
        return None
    with open(path, encoding="utf-8") as f:
        return f.read()


def read_csv(path):
    """(data (N, 21), names) of a trajectory.csv; ValueError if malformed or empty."""
    with open(path, encoding="utf-8") as f:
        names = [n.strip() for n in f.readline().strip().split(",")]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # "input contained no data": checked below
        data = np.loadtxt(path, delimiter=",", skiprows=1, ndmin=2)
    if data.shape[0] == 0:
        raise ValueError(f"{path}: trajectory has no rows")
    if data.shape[1] != len(names):
        raise ValueError(f"{path}: header has {len(names)} columns, rows have {data.shape[1]}")
    return data, names


def read_npz(path):
    """(data, names, scenario TOML or None, summary JSON text or None) of a trajectory.npz."""
    try:
        archive = np.load(path, allow_pickle=False)
    except (OSError, ValueError, zipfile.BadZipFile) as e:
        raise ValueError(f"{path}: not a readable npz file ({e}); a run that was killed before it closed "
                         f"the file leaves no central directory: resume it with `lgvi run --resume`") from None
    with archive as z:
        if "trajectory" not in z.files:
            raise ValueError(f"{path}: no trajectory.npy entry")
        data = np.array(z["trajectory"], dtype=float)
        names = list(z["columns"]) if "columns" in z.files else list(COLUMNS)
        scenario = _text(z["scenario"]) if "scenario" in z.files else None
        summary = _text(z["summary"]) if "summary" in z.files else None
    return data, names, scenario, summary


def read_h5(path):
    """(data, names, scenario TOML or None, summary JSON text or None) of a trajectory.h5 (needs h5py)."""
    try:
        import h5py
    except ImportError:
        raise ImportError(f"{path}: reading HDF5 needs h5py (Debian: apt-get install python3-h5py)") from None
    with h5py.File(path, "r") as f:
        if "trajectory" not in f:
            raise ValueError(f"{path}: no /trajectory dataset")
        ds = f["trajectory"]
        data = np.array(ds[...], dtype=float)
        names = list(ds.attrs["columns"]) if "columns" in ds.attrs else list(COLUMNS)
        scenario = _text(f.attrs["scenario"]) if "scenario" in f.attrs else None
        summary = _text(f.attrs["summary"]) if "summary" in f.attrs else None
    return data, names, scenario, summary


#: The particle exports for viewers ([output] format = "xyz" | "vtk" | "lammps-dump"):
#: sites, not the trajectory's columns, so lgvi.load refuses them (_refuse_export).
EXPORT_FILES = ("trajectory.xyz", "trajectory.pvd", "trajectory.lammpstrj")


def _refuse_export(path):
    raise ValueError(f"{path}: an export for viewers ([output] format = \"xyz\" for OVITO, \"vtk\" for "
                     f"ParaView, \"lammps-dump\" for LAMMPS), not a trajectory lgvi.load reads; for analysis "
                     f"run the scenario with "
                     f"[output] format = \"csv\", \"npz\" or \"hdf5\" (or lgvi.simulate)")


def _trajectory_in(folder):
    for name in TRAJECTORY_FILES:
        path = os.path.join(folder, name)
        if os.path.isfile(path):
            return path
    for name in EXPORT_FILES:
        path = os.path.join(folder, name)
        if os.path.isfile(path):
            _refuse_export(path)
    raise FileNotFoundError(f"{folder}: no trajectory file here (looked for {', '.join(TRAJECTORY_FILES)})")


def load(path):
    """Load a run folder of the CLI, or a trajectory file (.csv, .npz, .h5), into a Result.

    The exports for viewers (trajectory.xyz, .pvd, .lammpstrj) are refused
    with a ValueError saying to use csv, npz or hdf5 for analysis: they hold
    the bodies' spheres for OVITO, ParaView and LAMMPS, not the trajectory's
    columns.

    A folder is read through its trajectory.csv, trajectory.npz or trajectory.h5
    and its summary.json; a file's summary and scenario come from the file
    itself (npz, HDF5) or from summary.json and scenario.toml next to it.
    Quaternions (Result.q) are scalar-first (w, x, y, z). Numbers round-trip
    exactly: lgvi.load(dir).data equals the arrays of lgvi.simulate() bit for
    bit. FileNotFoundError if nothing is there; ValueError if the file is
    malformed; ImportError for .h5 without h5py.
    """
    path = os.fspath(path)
    if os.path.isdir(path):
        folder, file = path, _trajectory_in(path)
    elif os.path.isfile(path):
        folder, file = os.path.dirname(path) or ".", path
    else:
        raise FileNotFoundError(f"{path}: no such run folder or trajectory file")
    scenario = summary_text = None
    ext = os.path.splitext(file)[1].lower()
    if ext == ".csv":
        data, names = read_csv(file)
    elif ext == ".npz":
        data, names, scenario, summary_text = read_npz(file)
    elif ext in (".h5", ".hdf5"):
        data, names, scenario, summary_text = read_h5(file)
    elif ext in {os.path.splitext(name)[1] for name in EXPORT_FILES} | {".vtp"}:  # .vtp: a vtk export's frame
        _refuse_export(file)
    else:
        raise ValueError(f"{file}: unknown trajectory format (expected .csv, .npz or .h5)")
    names = [_text(n).strip() for n in names]
    long = bodies_columns(names) is not None
    if not long:
        _check_columns(names, file)
        if data.ndim != 2 or data.shape[1] != len(names):
            raise ValueError(f"{file}: trajectory has shape {data.shape}, expected (rows, {len(names)})")
    summary = _summary(folder, summary_text)
    if scenario is None:
        scenario = _read_side_file(folder, "scenario.toml")
    result = Result(data, summary, scenario, source=file, columns=names,
                    names=_body_names(folder, summary) if long else None)
    if long:
        result._wheel_rows = _read_side_table(folder, "wheels.csv")  # the long layout's wheels ([[bodies.wheel]])
    result._sensors = _read_side_table(folder, "sensors.csv")  # what a controller's sensors read ([[sensor]])
    return result


def load_bodies(run_dir):
    """The lists of bodies of a many-body ([[bodies]]) run folder of the CLI: one dict per body, in scenario
    order, with its set-up (``name``, ``mass``, ``inertia``, ``balls``, ... as summary.json's setup.bodies)
    and ``final``: its final state (``position``, ``quaternion`` scalar-first, ``momentum``, ``w``; absent
    for a run that failed before its first step).

    They are summary.json's setup.bodies and final_bodies up to 10 000 bodies, and beyond (or with
    ``[output] body_lists = "file"``) the file summary.json's body_lists names (bodies.jsonl, one body a line),
    read line by line. FileNotFoundError if the folder has no summary.json or the file it names is missing;
    ValueError for a single-body run or a malformed file.
    """
    folder = os.fspath(run_dir)
    summary_text = _read_side_file(folder, "summary.json")
    if summary_text is None:
        raise FileNotFoundError(2, "No such file or directory", os.path.join(folder, "summary.json"))
    summary = _summary(folder, summary_text)
    lists = summary.get("body_lists")
    if lists is None:
        setups = summary.get("setup", {}).get("bodies")
        if setups is None:
            raise ValueError(f"{folder}: summary.json has no lists of bodies (a single-body run's final state is its "
                             "final; a run of [[bodies]] has setup.bodies or body_lists)")
        finals = summary.get("final_bodies", [])
        bodies = []
        for a, setup in enumerate(setups):
            body = dict(setup)
            if a < len(finals):
                body["final"] = {k: v for k, v in finals[a].items() if k != "name"}
            bodies.append(body)
        return bodies
    if not isinstance(lists, dict) or not isinstance(lists.get("file"), str):
        raise ValueError(f"{folder}: summary.json's body_lists must name its file, as {{\"file\": \"bodies.jsonl\", "
                         f"\"bodies\": N}}; got {lists!r}")
    return _body_lines(folder, lists, _json_line)


def _body_lines(folder, lists, parse):
    """parse(line) of each line of the file summary.json's body_lists names (one body a line), checked against
    the number of bodies it gives. parse raises ValueError saying what is wrong with a line; the error names
    the file and the line."""
    path = os.path.join(folder, lists["file"])
    values = []
    with open(path, encoding="utf-8") as f:
        for number, line in enumerate(f, 1):
            try:
                values.append(parse(line))
            except ValueError as e:
                raise ValueError(f"{path}:{number}: {e}") from None
    if len(values) != lists.get("bodies"):
        raise ValueError(f"{path}: holds {len(values)} bodies where the summary's body_lists says "
                         f"{lists.get('bodies')}")
    return values


def _json_line(line):
    """A line of the lists of bodies, whole."""
    try:
        return json.loads(line)
    except json.JSONDecodeError as e:
        raise ValueError(f"not valid JSON ({e})") from None


def _name_of_line(line, decoder=json.JSONDecoder(), start='{"name": '):
    """The name of a line of the lists of bodies: its first member, decoded alone, not the whole line."""
    try:
        return decoder.raw_decode(line, len(start))[0] if line.startswith(start) else json.loads(line)["name"]
    except (ValueError, KeyError, TypeError):
        raise ValueError("not a body's line of the lists of bodies (a JSON object with its name first)") from None


def _body_names(folder, summary):
    """The bodies' names from the file of the lists of bodies the summary names (summary.json's body_lists:
    beyond 10 000 bodies, or with [output] body_lists = "file"), one body a line; None without one (the
    names are then the summary's final_bodies')."""
    lists = summary.get("body_lists")
    if not isinstance(lists, dict) or not isinstance(lists.get("file"), str):
        return None
    try:
        return _body_lines(folder, lists, _name_of_line)
    except FileNotFoundError:  # a trajectory file (npz, HDF5: its own summary) taken away from its folder
        warnings.warn(f"{os.path.join(folder, lists['file'])}: not there (the summary's body_lists names it); the "
                      "bodies are named body0, body1, ...", stacklevel=3)
        return None


def _read_side_table(folder, name):
    """A table the CLI writes beside the trajectory (sensors.csv, wheels.csv): column name -> array; {} if
    the folder has none."""
    path = os.path.join(folder, name)
    if not os.path.isfile(path):
        return {}
    with open(path, encoding="utf-8") as f:
        names = [n.strip() for n in f.readline().strip().split(",")]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # a run that failed before its first row: the header alone
        values = np.loadtxt(path, delimiter=",", skiprows=1, ndmin=2).reshape(-1, len(names))
    return {n: values[:, j].copy() for j, n in enumerate(names)}


def _summary(folder, summary_text):
    """The summary dict from the file's own text or the folder's summary.json."""
    if summary_text is None:
        summary_text = _read_side_file(folder, "summary.json")
    try:
        return json.loads(summary_text) if summary_text else {}
    except json.JSONDecodeError as e:
        raise ValueError(f"{folder}: summary is not valid JSON ({e})") from None


def load_run(run_dir):
    """Load a run directory.

    Returns ``(columns, summary)``: a dict mapping each trajectory header
    name to a 1-D float array, and the parsed summary.json. Reads
    trajectory.csv, or else trajectory.npz or trajectory.h5. Raises OSError
    for missing files and ValueError for a malformed or empty trajectory.
    """
    return load_columns(run_dir)


def load_columns(path):
    """(columns dict, summary dict) of a run folder (any format) for lgvi.plot.

    OSError if the trajectory or summary.json is missing, ValueError if malformed.
    """
    path = os.fspath(path)
    if os.path.isdir(path) and os.path.isfile(os.path.join(path, "trajectory.csv")):
        # The CLI's own layout: header names as written (checked by the plot's caller).
        data, names = read_csv(os.path.join(path, "trajectory.csv"))
        with open(os.path.join(path, "summary.json"), encoding="utf-8") as f:
            summary = json.load(f)
        return {name: data[:, i] for i, name in enumerate(names)}, summary
    result = load(path)
    if not result.summary and os.path.isdir(path):
        raise FileNotFoundError(2, "No such file or directory", os.path.join(path, "summary.json"))
    if len(result) == 0:
        raise ValueError(f"{result.source}: trajectory has no rows")
    return result.columns, result.summary
