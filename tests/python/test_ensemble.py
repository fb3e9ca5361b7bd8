"""`lgvi ensemble` and lgvi.ensemble: members.csv identical for 1 thread, 2 threads,
`mpirun -n 2` and `mpirun -n 2` with 2 threads per rank; the draws (reproducible, with the stated distributions) and grids; a failing
member recorded while the others complete; errors up front naming the member and the key;
SIGTERM and a killed MPI rank, then --resume, byte-identical to an uninterrupted ensemble;
the Python function on a process pool, mpi4py and Dask, equal to the CLI's bytes.

Run by ctest with LGVI_BINARY set. mpirun as root needs OMPI_ALLOW_RUN_AS_ROOT (set here).
"""
import csv
import os
import pathlib
import shutil
import signal
import subprocess
import sys
import time

import numpy as np
import pytest

BINARY = os.environ.get("LGVI_BINARY")
SOURCE = pathlib.Path(os.environ.get("LGVI_SOURCE_DIR", pathlib.Path(__file__).resolve().parents[2]))
pytestmark = pytest.mark.skipif(BINARY is None, reason="LGVI_BINARY not set (run through ctest)")
MPIRUN = shutil.which("mpirun")
needs_mpi = pytest.mark.skipif(MPIRUN is None, reason="mpirun (openmpi-bin) not installed")
MPI_ENV = dict(os.environ, OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1",
               OMPI_MCA_rmaps_base_oversubscribe="1")


def base_scenario(tmp_path, duration=20.0, contact=False):
    text = (SOURCE / "scenarios" / "paper-orbit.toml").read_text()
    text = text.replace("duration = 1000.0", f"duration = {duration}")
    assert f"duration = {duration}" in text
    if contact:  # a ball touching the source stops the run: a failed member
        text = text.replace("mu = 1.0\n", "mu = 1.0\nstop_at_contact = true\n")
        assert "stop_at_contact = true" in text
    (tmp_path / "paper-orbit.toml").write_text(text)


SWEEP = """[ensemble]
scenario = "paper-orbit.toml"
members = {members}
seed = 7

[[vary]]
key = "initial.w"
normal = {{ mean = [1.0, 2.0, 3.0], std = [0.05, 0.05, 0.05] }}

[[vary]]
key = "initial.quaternion"
rotation = "uniform"
"""


# 2 momenta x 3 steps; momentum (0, 0, 0) drops the body onto the source: with
# stop_at_contact that member fails (the grid test says when).
CONTACT_GRID = """[ensemble]
scenario = "paper-orbit.toml"
[[vary]]
key = "initial.momentum"
values = [[0.0, 1.0, 0.0], [0.0, 0.0, 0.0]]
[[vary]]
key = "integrator.step"
values = [0.01, 0.02, 0.005]
"""


def sweep(tmp_path, members=24, duration=20.0, text=None, contact=False):
    base_scenario(tmp_path, duration, contact)
    path = tmp_path / "sweep.toml"
    path.write_text(text if text is not None else SWEEP.format(members=members))
    return path


def ensemble(*args, env=None, mpi=0):
    cmd = ([MPIRUN, "-n", str(mpi), "--oversubscribe"] if mpi else []) + [BINARY, "ensemble", *map(str, args), "-q", "--no-figures"]
    return subprocess.run(cmd, capture_output=True, text=True, env=env or MPI_ENV, timeout=300)


def test_members_csv_is_identical_for_one_thread_two_threads_and_two_ranks(tmp_path):
    path = sweep(tmp_path)
    outs = {}
    for name, extra, mpi in (("t1", ["--threads", "1"], 0), ("t2", ["--threads", "2"], 0)) + (
            (("mpi2", [], 2), ("mpi2-threads2", ["--threads", "2"], 2)) if MPIRUN else ()):
        proc = ensemble(path, "--out", tmp_path / name, *extra, mpi=mpi)
        assert proc.returncode == 0, proc.stderr
        outs[name] = (tmp_path / name / "members.csv").read_bytes()
    assert len(outs["t1"].splitlines()) == 25
    for name, data in outs.items():
        assert data == outs["t1"], name
    # The Python function, run here and on a process pool: the same bytes.
    import concurrent.futures
    import lgvi
    sc = lgvi.Scenario.from_toml(tmp_path / "paper-orbit.toml")
    vary = [{"key": "initial.w", "normal": {"mean": [1.0, 2.0, 3.0], "std": [0.05, 0.05, 0.05]}},
            {"key": "initial.quaternion", "rotation": "uniform"}]
    assert lgvi.ensemble(sc, vary, members=24, seed=7).text.encode() == outs["t1"]
    with concurrent.futures.ProcessPoolExecutor(2) as pool:
        assert lgvi.ensemble(sc, vary, members=24, seed=7, executor=pool).text.encode() == outs["t1"]


def test_draws_have_the_stated_distributions(tmp_path):
    # 4000 members of a zero-length run (the draws alone). Normal(1, 0.1):
    # the sample mean within 4 sigma / sqrt(n) = 0.0063 of 1, the sample std
    # within 4 sigma / sqrt(2n) = 0.0045 of 0.1. Uniform(-2, 3): inside, mean
    # within 4 * 5 / sqrt(12 n) of 0.5. Uniform rotations: unit, and each
    # component's mean square 1/4: q_i^2 ~ Beta(1/2, 3/2) on S^3, variance
    # 1/16, so within 4 sqrt(1/16 / n) = 0.0158.
    text = """[ensemble]
scenario = "paper-orbit.toml"
members = 4000
seed = 3
[[vary]]
key = "integrator.tolerance"
uniform = { low = 1e-15, high = 1e-14 }
[[vary]]
key = "initial.w"
normal = { mean = [1.0, 2.0, 3.0], std = [0.1, 0.1, 0.1] }
[[vary]]
key = "initial.position"
uniform = { low = [6.0, -2.0, 0.0], high = [8.0, 3.0, 0.0] }
[[vary]]
key = "initial.quaternion"
rotation = "uniform"
"""
    path = sweep(tmp_path, duration=0.0, text=text)
    proc = ensemble(path, "--out", tmp_path / "out", "--threads", "2")
    assert proc.returncode == 0, proc.stderr
    data = np.genfromtxt(tmp_path / "out" / "members.csv", delimiter=",", names=True)
    w0 = data["initialw0"]
    assert abs(w0.mean() - 1.0) < 0.0063 and abs(w0.std() - 0.1) < 0.0045
    y = data["initialposition1"]
    assert y.min() > -2.0 and y.max() < 3.0 and abs(y.mean() - 0.5) < 4 * 5 / np.sqrt(12 * 4000)
    q = np.stack([data[f"initialquaternion{i}"] for i in range(4)], axis=1)
    assert np.max(np.abs(np.linalg.norm(q, axis=1) - 1)) < 1e-15 * 8
    assert np.all(np.abs((q ** 2).mean(axis=0) - 0.25) < 0.0158)
    # Reproducible: the same seed gives the same file; another seed another.
    again = ensemble(path, "--out", tmp_path / "again", "--threads", "1")
    assert again.returncode == 0
    assert (tmp_path / "again" / "members.csv").read_bytes() == (tmp_path / "out" / "members.csv").read_bytes()


def test_grid_is_the_product_last_key_fastest_and_a_failing_member_is_recorded(tmp_path):
    # momentum (0, 0, 0) drops the body onto the field's source (free fall
    # from r = 8 takes pi/2 sqrt(r^3 / 2 mu) = 25 < 60): with stop_at_contact
    # that member fails, recorded with its message; the others complete.
    # (Contact is checked at the steps: much coarser steps can jump past it.)
    path = sweep(tmp_path, duration=60.0, text=CONTACT_GRID, contact=True)
    proc = ensemble(path, "--out", tmp_path / "out")
    assert proc.returncode == 0, proc.stderr
    lines = (tmp_path / "out" / "members.csv").read_text().splitlines()
    header = lines[0].split(",")
    assert header[:6] == ["index", "initial.momentum[0]", "initial.momentum[1]", "initial.momentum[2]",
                          "integrator.step", "completed"]
    rows = [line.split(",") for line in lines[1:]]
    assert [r[0] for r in rows] == [str(i) for i in range(6)]
    assert [float(r[4]) for r in rows] == [0.01, 0.02, 0.005] * 2
    assert [r[2] for r in rows] == ["1", "1", "1", "0", "0", "0"]
    assert [r[5] for r in rows[:3]] == ["1"] * 3
    assert [r[5] for r in rows[3:]] == ["0"] * 3
    assert all(r[6] != "" for r in rows[3:])  # the failure's message
    show = subprocess.run([BINARY, "show", tmp_path / "out"], capture_output=True, text=True)
    assert show.returncode == 0 and "failed                     3" in show.stdout


@pytest.mark.parametrize("mpi", [0, pytest.param(2, marks=needs_mpi)])
def test_a_member_failing_at_its_first_step_is_recorded(tmp_path, mpi):
    """A ball placed on the central field's source (with stop_at_contact) is not something the scenario reader
    rejects: the member's run fails at step 0, which is recorded with its message while the other members
    complete; the table is the same on threads and on ranks."""
    base_scenario(tmp_path, duration=5.0, contact=True)
    (tmp_path / "sweep.toml").write_text(
        '[ensemble]\nscenario = "paper-orbit.toml"\n[[vary]]\nkey = "initial.position"\n'
        # the body's centre of mass at (1/2, sqrt(3)/6, 0) of its triangle puts ball 0 on the source
        'values = [[8.0, 0.0, 0.0], [0.5, 0.28867513459481287, 0.0], [0.0, 8.0, 0.0]]\n')
    threads = ensemble(tmp_path / "sweep.toml", "--out", tmp_path / "threads", "--threads", "2")
    assert threads.returncode == 0, threads.stderr
    rows = list(csv.DictReader((tmp_path / "threads" / "members.csv").open()))
    assert [r["completed"] for r in rows] == ["1", "0", "1"]
    assert rows[1]["error"].startswith("step 0 (from t = 0) failed: ball 0 reached the centre of the central field")
    assert rows[1]["steps"] == "0" and rows[0]["steps"] == rows[2]["steps"] == "500"
    if mpi:
        ranks = ensemble(tmp_path / "sweep.toml", "--out", tmp_path / "ranks", mpi=mpi)
        assert ranks.returncode == 0, ranks.stderr
        assert (tmp_path / "ranks" / "members.csv").read_bytes() == (tmp_path / "threads" / "members.csv").read_bytes()


@pytest.mark.parametrize("text, expected", [
    (SWEEP.format(members=4).replace('rotation = "uniform"', 'normal = { mean = [1.0, 0.0, 0.0, 0.0], '
                                     'std = [0.1, 0.1, 0.1, 0.1] }'),
     ["member 0", "initial.quaternion"]),
    (SWEEP.format(members=4).replace('key = "initial.w"', 'key = "initial.wx"'),
     ["member 0", "initial.wx", "unknown key"]),
    (SWEEP.format(members=4).replace('key = "initial.w"', 'key = "nothing.w"'), ["vary[0].key", "no table"]),
    (SWEEP.format(members=4).replace("seed = 7\n", ""), ["ensemble.seed", "missing"]),
    (SWEEP.format(members=4).replace("seed = 7", "seed = 7\ncolour = 1"),
     ["ensemble.colour", "unknown key; allowed here: scenario, members, seed, trajectories, metrics, settle_band_deg"]),
    # The sweep file is read by the scenario's reader (src/io/toml_reader.hpp): it says what was given.
    (SWEEP.format(members=4).replace("std = [0.05, 0.05, 0.05]", 'std = [0.05, "a", 0.05]'),
     ["vary[0].normal.std[1]", "must be a number, got a string"]),
    (SWEEP.format(members=4).replace("std = [0.05, 0.05, 0.05]", "std = []"),
     ["vary[0].normal.std", "must be a number or a non-empty array of numbers, got an empty array"]),
    (SWEEP.format(members=4) + '[[vary]]\nkey = "integrator.step"\nvalues = [0.01]\n', ["vary", "not both"]),
    (SWEEP.format(members=4).replace("std = [0.05, 0.05, 0.05]", "std = [0.05, 0.05]"), ["vary[0].normal", "same length"]),
    (SWEEP.format(members=4).replace('key = "initial.w"\nnormal = { mean = [1.0, 2.0, 3.0], std = [0.05, 0.05, 0.05] }',
                                     'key = "integrator.step"\nnormal = { mean = 0.0, std = 0.01 }'),
     ["member 1", "integrator.step", "> 0"]),
])
def test_bad_sweeps_fail_up_front_in_one_line(tmp_path, text, expected):
    path = sweep(tmp_path, text=text)
    proc = ensemble(path, "--out", tmp_path / "out")
    assert proc.returncode == 2
    message = proc.stderr.strip()
    assert "\n" not in message and message.startswith("lgvi: error:"), message
    for e in expected:
        assert e in message, message
    assert not (tmp_path / "out" / "members.csv").exists()


def test_an_existing_ensemble_folder_is_not_overwritten(tmp_path):
    path = sweep(tmp_path, members=2)
    assert ensemble(path, "--out", tmp_path / "out").returncode == 0
    proc = ensemble(path, "--out", tmp_path / "out")
    assert proc.returncode == 2 and "--resume" in proc.stderr


def wait_for_rows(journal, rows, timeout=60):
    start = time.time()
    while time.time() - start < timeout:
        if journal.exists() and journal.read_text().count("\n") >= rows:
            return
        time.sleep(0.02)
    raise AssertionError("the ensemble wrote no rows")


@pytest.mark.parametrize("sig, status", [(signal.SIGTERM, 143), (signal.SIGINT, 130)])
def test_a_signal_then_resume_gives_the_uninterrupted_bytes(tmp_path, sig, status):
    # 60 members of 20000 steps (~5 ms each). The exit status is 128 + the signal's number, as a shell reports.
    path = sweep(tmp_path, members=60, duration=200.0)
    whole = ensemble(path, "--out", tmp_path / "whole", "--threads", "2")
    assert whole.returncode == 0, whole.stderr
    proc = subprocess.Popen([BINARY, "ensemble", path, "--out", tmp_path / "cut", "--threads", "2", "-q"],
                            stderr=subprocess.PIPE, text=True)
    wait_for_rows(tmp_path / "cut" / "journal.csv", 5)
    proc.send_signal(sig)
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == status, err
    partial = (tmp_path / "cut" / "members.csv").read_text().splitlines()
    assert 5 <= len(partial) - 1 < 60 and "--resume" in err
    indices = [int(line.split(",")[0]) for line in partial[1:]]
    assert indices == sorted(indices)  # a valid partial table, in member order
    resumed = ensemble("--resume", tmp_path / "cut")
    assert resumed.returncode == 0, resumed.stderr
    assert (tmp_path / "cut" / "members.csv").read_bytes() == (tmp_path / "whole" / "members.csv").read_bytes()


@pytest.mark.parametrize("mpi,threads", [(0, 2), pytest.param(2, 1, marks=needs_mpi),
                                         pytest.param(2, 2, marks=needs_mpi)])
def test_timings_has_each_members_wall_time_and_rank(tmp_path, mpi, threads):
    """timings.csv (kept apart from members.csv, which must not depend on timing): one line per member, in the
    order they finished, with its wall time and the rank that ran it; under mpirun -n 2 both ranks ran members
    (rank 0 on threads beside its coordinator, rank 1 by hand-out), 1 or 2 at once per rank."""
    path = sweep(tmp_path, members=24, duration=200.0)
    proc = ensemble(path, "--out", tmp_path / "out", "--threads", str(threads), mpi=mpi)
    assert proc.returncode == 0, proc.stderr
    lines = (tmp_path / "out" / "timings.csv").read_text().splitlines()
    assert lines[0] == "index,wall_seconds,rank"
    rows = [line.split(",") for line in lines[1:]]
    assert sorted(int(r[0]) for r in rows) == list(range(24))
    # 20000 steps of the paper orbit take milliseconds; a wall time outside (0, 10 s) is not a measurement.
    assert all(0.0 < float(r[1]) < 10.0 for r in rows)
    assert {int(r[2]) for r in rows} == ({0, 1} if mpi else {0})


def test_a_body_by_name_and_trajectories_all(tmp_path):
    """A key of one body by its name (bodies.secondary.omega) varies that body only; trajectories = "all" keeps
    each member's run folder, whose scenario holds the member's value and whose summary's final state is the
    member's row in members.csv, digit for digit."""
    import json
    import tomllib

    text = (SOURCE / "scenarios" / "binary-asteroid.toml").read_text().replace("duration = 400.0", "duration = 2.0")
    assert "duration = 2.0" in text
    (tmp_path / "binary.toml").write_text(text)
    (tmp_path / "sweep.toml").write_text('[ensemble]\nscenario = "binary.toml"\ntrajectories = "all"\n'
                                         '[[vary]]\nkey = "bodies.secondary.omega"\n'
                                         'values = [[0.0, 0.0, 0.1], [0.0, 0.0, 0.3]]\n')
    proc = ensemble(tmp_path / "sweep.toml", "--out", tmp_path / "out", "--threads", "2")
    assert proc.returncode == 0, proc.stderr
    table = (tmp_path / "out" / "members.csv").read_text().splitlines()
    header = table[0].split(",")
    assert header[:4] == ["index"] + [f"bodies.secondary.omega[{k}]" for k in range(3)]
    for m, omega in enumerate(([0.0, 0.0, 0.1], [0.0, 0.0, 0.3])):
        run = tmp_path / "out" / "members" / f"{m:06d}"
        scenario = tomllib.loads((run / "scenario.toml").read_text())
        assert [b["name"] for b in scenario["bodies"]] == ["primary", "secondary"]
        assert scenario["bodies"][1]["omega"] == omega and scenario["bodies"][0]["omega"] == [0.0, 0.0, 0.6]
        row = dict(zip(header, table[1 + m].split(",")))
        final = json.loads((run / "summary.json").read_text())["final_bodies"][1]
        assert final["name"] == "secondary"
        for k, axis in enumerate("xyz"):
            assert float(row[f"secondary.{axis}"]) == final["position"][k]


def test_show_prints_the_quantiles_of_members_csv_and_reads_a_journal_alone(tmp_path):
    """lgvi show DIR: the count, failures and min / median / 90 % / max of each error over the completed
    members, equal (to the 4 digits printed) to numpy's linear quantiles of members.csv; with members.csv gone
    (a run killed by kill -9 leaves only the journal) the same from journal.csv, saying so."""
    import numpy as np

    path = sweep(tmp_path, members=24)
    proc = ensemble(path, "--out", tmp_path / "out", "--threads", "2")
    assert proc.returncode == 0, proc.stderr
    table = np.genfromtxt(tmp_path / "out" / "members.csv", delimiter=",", names=True)

    def shown():
        p = subprocess.run([BINARY, "show", str(tmp_path / "out")], capture_output=True, text=True)
        assert p.returncode == 0, p.stderr
        return p.stdout

    for text in (shown(), None):
        if text is None:
            (tmp_path / "out" / "members.csv").unlink()
            text = shown()
            assert "from journal.csv" in text and "--resume" in text
        assert "(24 of 24 members)" in text and "\nfailed                     0\n" in text
        for name in ("max_abs_energy_error", "max_abs_quat_norm_error", "max_momentum_error"):
            line = next(line for line in text.splitlines() if line.strip().startswith(name))
            printed = [float(v) for v in line.split(None, 1)[1].split(" / ")]
            expected = np.quantile(table[name], [0.0, 0.5, 0.9, 1.0])
            np.testing.assert_allclose(printed, expected, rtol=5e-4)  # printed with 4 significant digits


def test_a_momentum_the_members_do_not_conserve_is_labelled_a_change(tmp_path):
    """Under a forcing the angular momentum is not conserved: its column measures a change, not an error
    of the method. lgvi ensemble lists it in changes_not_errors.json, lgvi show marks its row "(a change)"
    and the figures' EnsembleResult carries it; the unforced base marks only the linear momentum (a central
    field does not conserve it), and max_momentum_error stays an error there."""
    import json

    from lgvi import plot

    def run(out, forced):
        path = sweep(tmp_path, members=4, duration=2.0)
        if forced:
            scenario = tmp_path / "paper-orbit.toml"
            scenario.write_text(scenario.read_text() + '\n[[forcing]]\nkind = "torque"\nvalue = [0.0, 0.0, 0.01]\n')
        proc = ensemble(path, "--out", tmp_path / out)
        assert proc.returncode == 0, proc.stderr
        shown = subprocess.run([BINARY, "show", str(tmp_path / out)], capture_output=True, text=True)
        assert shown.returncode == 0, shown.stderr
        marks = json.loads((tmp_path / out / "changes_not_errors.json").read_text())
        assert plot._ensemble_table(str(tmp_path / out)).changes_not_errors == tuple(marks)
        return shown.stdout, marks

    text, marks = run("forced", True)
    assert marks == ["max_momentum_error", "max_linear_momentum_error"]
    assert "  max_momentum_error (a change) " in text and "not an error of the method" in text
    text, marks = run("free", False)
    assert marks == ["max_linear_momentum_error"]
    assert "  max_momentum_error " in text and "(a change)" not in text


def test_figures_of_an_ensemble(tmp_path):
    """Without --no-figures, a completed ensemble draws error_distribution.png and error_vs_varied.png (lgvi.plot).
    This sweep varies 7 values (w: 3, the quaternion: 4), all of them panels, four a row: a 2 x 4 grid, whose
    size in pixels is 4 x 3.6 by 2 x 3.2 inches at the plotting path's DPI."""
    import matplotlib.image

    from lgvi import plot

    path = sweep(tmp_path, members=8)
    proc = subprocess.run([BINARY, "ensemble", str(path), "--out", str(tmp_path / "out"), "-q", "--threads", "2"],
                          capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr
    for name in ("error_distribution.png", "error_vs_varied.png"):
        assert (tmp_path / "out" / name).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    height, width = matplotlib.image.imread(tmp_path / "out" / "error_vs_varied.png").shape[:2]
    assert (width, height) == (round(4 * 3.6 * plot.DPI), round(2 * 3.2 * plot.DPI))


def test_resume_after_a_torn_journal_line_gives_the_uninterrupted_bytes(tmp_path):
    """A process killed while appending leaves a last line without its newline. --resume cuts it, so the next
    row appended starts a line of its own; before, that row was glued onto the fragment and the journal held a
    line with the fragment's index and too many fields (a second interruption would have kept it)."""
    path = sweep(tmp_path, members=12)
    whole = ensemble(path, "--out", tmp_path / "whole", "--threads", "2")
    assert whole.returncode == 0, whole.stderr
    rows = (tmp_path / "whole" / "journal.csv").read_text().splitlines()
    cut = tmp_path / "cut"
    cut.mkdir()
    for name in ("sweep.toml", "scenario.toml"):
        (cut / name).write_bytes((tmp_path / "whole" / name).read_bytes())
    # Five whole rows, then half of a sixth.
    (cut / "journal.csv").write_text("\n".join(rows[:5]) + "\n" + rows[5][: len(rows[5]) // 2])
    resumed = ensemble("--resume", cut, "--threads", "2")
    assert resumed.returncode == 0, resumed.stderr
    assert (cut / "members.csv").read_bytes() == (tmp_path / "whole" / "members.csv").read_bytes()
    fields = len(rows[0].split(","))
    journal = (cut / "journal.csv").read_text()
    assert journal.endswith("\n") and all(len(line.split(",")) == fields for line in journal.splitlines())
    assert sorted(journal.splitlines()) == sorted(rows)


@pytest.mark.parametrize("mpi", [0, pytest.param(2, marks=needs_mpi)])
def test_progress_on_a_terminal(tmp_path, mpi):
    """On a terminal (a pseudo-terminal here) the runner shows members done / total, failures, rate and time
    left, on threads and under mpirun (rank 0 draws it; a rank's stderr is a pipe to mpirun, so there it takes
    --progress); the last state shown is the whole ensemble."""
    import pty
    import re as regex

    path = sweep(tmp_path, members=16)
    cmd = ([MPIRUN, "-n", str(mpi), "--oversubscribe"] if mpi else []) + [
        BINARY, "ensemble", str(path), "--out", str(tmp_path / "out"), "--no-figures"] + (
        ["--progress"] if mpi else ["--threads", "2"])
    leader, follower = pty.openpty()
    proc = subprocess.Popen(cmd, stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL, stderr=follower, env=MPI_ENV)
    os.close(follower)
    shown = b""
    while True:
        try:
            chunk = os.read(leader, 4096)
        except OSError:  # the terminal closed: every writer has exited
            break
        if not chunk:
            break
        shown += chunk
    os.close(leader)
    assert proc.wait(timeout=120) == 0, shown
    states = regex.findall(rb"lgvi ensemble: (\d+)/16 members, (\d+) failed, \S+ members/s, ~\d+ s left", shown)
    assert states, shown
    assert states[-1] == (b"16", b"0")
    done = [int(d) for d, _ in states]
    assert done == sorted(done)


@needs_mpi
@pytest.mark.parametrize("threads", [1, 2])
def test_a_killed_rank_loses_no_finished_member_and_resume_completes(tmp_path, threads):
    """kill -9 of rank 1 (running one member, or two on threads): what rank 0 received stays, --resume completes."""
    path = sweep(tmp_path, members=60, duration=200.0)
    whole = ensemble(path, "--out", tmp_path / "whole", "--threads", "1")
    assert whole.returncode == 0, whole.stderr
    proc = subprocess.Popen([MPIRUN, "-n", "2", "--oversubscribe", BINARY, "ensemble", path, "--out", tmp_path / "cut",
                             "-q", "--threads", str(threads)], stderr=subprocess.PIPE, stdout=subprocess.PIPE,
                            text=True, env=MPI_ENV)
    journal = tmp_path / "cut" / "journal.csv"
    wait_for_rows(journal, 5)
    # Rank 1: the lgvi process whose environment says OMPI_COMM_WORLD_RANK=1.
    victim = None
    for pid in os.listdir("/proc"):
        if not pid.isdigit():
            continue
        try:
            env = pathlib.Path(f"/proc/{pid}/environ").read_bytes().split(b"\0")
            exe = os.readlink(f"/proc/{pid}/exe")
        except OSError:
            continue
        if exe.endswith("/lgvi") and b"OMPI_COMM_WORLD_RANK=1" in env and str(tmp_path).encode() in \
                pathlib.Path(f"/proc/{pid}/cmdline").read_bytes():
            victim = int(pid)
    assert victim is not None
    before = journal.read_text().count("\n")
    os.kill(victim, signal.SIGKILL)
    proc.communicate(timeout=60)
    assert proc.returncode != 0
    rows = journal.read_text().count("\n")
    assert rows >= before  # nothing rank 0 had received is lost
    resumed = ensemble("--resume", tmp_path / "cut")
    assert resumed.returncode == 0, resumed.stderr
    assert (tmp_path / "cut" / "members.csv").read_bytes() == (tmp_path / "whole" / "members.csv").read_bytes()


def test_dask_executor_gives_the_cli_bytes(tmp_path):
    distributed = pytest.importorskip("distributed")
    import lgvi
    path = sweep(tmp_path, members=8)
    assert ensemble(path, "--out", tmp_path / "cli").returncode == 0
    sc = lgvi.Scenario.from_toml(tmp_path / "paper-orbit.toml")
    vary = [{"key": "initial.w", "normal": {"mean": [1.0, 2.0, 3.0], "std": [0.05, 0.05, 0.05]}},
            {"key": "initial.quaternion", "rotation": "uniform"}]
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None) as cluster:
        with distributed.Client(cluster) as client:
            result = lgvi.ensemble(sc, vary, members=8, seed=7, executor=client.get_executor())
    assert result.text.encode() == (tmp_path / "cli" / "members.csv").read_bytes()


@needs_mpi
def test_mpi4py_executor_gives_the_cli_bytes(tmp_path):
    pytest.importorskip("mpi4py")
    path = sweep(tmp_path, members=8)
    assert ensemble(path, "--out", tmp_path / "cli").returncode == 0
    script = tmp_path / "run_mpi4py.py"
    script.write_text(f"""
import lgvi
from mpi4py.futures import MPIPoolExecutor
sc = lgvi.Scenario.from_toml({str(tmp_path / 'paper-orbit.toml')!r})
vary = [{{"key": "initial.w", "normal": {{"mean": [1.0, 2.0, 3.0], "std": [0.05, 0.05, 0.05]}}}},
        {{"key": "initial.quaternion", "rotation": "uniform"}}]
with MPIPoolExecutor() as pool:
    result = lgvi.ensemble(sc, vary, members=8, seed=7, executor=pool)
open({str(tmp_path / 'mpi4py.csv')!r}, "w").write(result.text)
""")
    env = dict(MPI_ENV, PYTHONPATH=os.pathsep.join(sys.path))
    proc = subprocess.run([MPIRUN, "-n", "2", "--oversubscribe", sys.executable, "-m", "mpi4py.futures", script],
                          capture_output=True, text=True, env=env, timeout=300)
    assert proc.returncode == 0, proc.stderr
    assert (tmp_path / "mpi4py.csv").read_bytes() == (tmp_path / "cli" / "members.csv").read_bytes()


@pytest.mark.parametrize("fmt,file", [("npz", "members.npz"), ("hdf5", "members.h5")])
def test_members_table_in_the_output_format_equals_the_csv_and_is_identical_for_threads_and_ranks(tmp_path, fmt,
                                                                                                  file):
    """With [output] format = "npz" or "hdf5" the members table is also written
    as arrays: every column equal to members.csv's (its 17 significant digits
    read back are the same doubles, so equality is exact; NaN where the CSV
    says nan), the failure messages as strings, and the file's bytes the same
    for 1 thread, 2 threads and mpirun -n 2 (HDF5 without timestamps)."""
    import csv
    path = sweep(tmp_path, duration=60.0, text=CONTACT_GRID, contact=True)
    scenario = tmp_path / "paper-orbit.toml"
    scenario.write_text(scenario.read_text().replace("[output]\n", f'[output]\nformat = "{fmt}"\n', 1))
    assert f'format = "{fmt}"' in scenario.read_text()
    tables = {}
    for name, extra, mpi in (("t1", ["--threads", "1"], 0), ("t2", ["--threads", "2"], 0)) + (
            (("mpi2", [], 2),) if MPIRUN else ()):
        proc = ensemble(path, "--out", tmp_path / name, *extra, mpi=mpi)
        assert proc.returncode == 0, proc.stderr
        tables[name] = (tmp_path / name / file).read_bytes()
    for name, data in tables.items():
        assert data == tables["t1"], name
    with open(tmp_path / "t1" / "members.csv", newline="") as f:
        rows = list(csv.reader(f))
    header, rows = rows[0], rows[1:]
    if fmt == "npz":
        arrays = dict(np.load(tmp_path / "t1" / file))
    else:
        h5py = pytest.importorskip("h5py")
        with h5py.File(tmp_path / "t1" / file, "r") as h:
            arrays = {k: h[k][()] for k in h.keys()}
        arrays["error"] = np.array([s.decode() for s in arrays["error"]])
    assert sorted(arrays) == sorted(header)
    for k, name in enumerate(header):
        column = [r[k] for r in rows]
        if name == "error":
            assert list(arrays[name]) == column and all(column[3:]) and not any(column[:3])
        elif name in ("index", "completed", "steps"):
            assert arrays[name].dtype == np.int64
            assert arrays[name].tolist() == [int(v) for v in column], name
        else:
            assert arrays[name].dtype == np.float64
            np.testing.assert_array_equal(arrays[name], np.array([float(v) for v in column]), err_msg=name)


def test_resuming_a_folder_from_before_the_labels_writes_them_and_refuses_a_change_of_model(tmp_path):
    """A folder begun by an lgvi without changes_not_errors.json: --resume writes the file (so the
    figures drawn at the end label the changes). If its members have a body given by mass + inertia in a
    central field, which that lgvi ran as a point mass, --resume refuses in one line: finishing them with
    the gravity-gradient model would mix two physics in one members.csv."""
    path = sweep(tmp_path, members=4, duration=2.0)
    out = tmp_path / "balls"
    assert ensemble(path, "--out", out).returncode == 0
    (out / "changes_not_errors.json").unlink()
    proc = ensemble("--resume", out)
    assert proc.returncode == 0, proc.stderr
    assert (out / "changes_not_errors.json").read_text() == '["max_linear_momentum_error"]\n'

    satellite = (tmp_path / "paper-orbit.toml").read_text()
    start, end = satellite.index("[body]"), satellite.index("[potential]")
    (tmp_path / "paper-orbit.toml").write_text(
        satellite[:start] + "[body]\nmass = 3.0\ninertia = [[1.0, 0.0, 0.0], [0.0, 2.0, 0.0], [0.0, 0.0, 2.5]]\n\n"
        + satellite[end:])
    out = tmp_path / "satellite"
    assert ensemble(path, "--out", out).returncode == 0
    (out / "changes_not_errors.json").unlink()
    proc = ensemble("--resume", out)
    assert proc.returncode == 2
    assert proc.stderr.count("\n") == 1 and "gravity-gradient" in proc.stderr and 'model = "point"' in proc.stderr


def test_a_forcing_key_is_varied_by_its_index(tmp_path):
    # "forcing.0.k_p": the first [[forcing]] entry's gain. Each member is the run of the scenario with that
    # value written in: its final state equal to the last bit (members.csv's 17 digits read back exactly).
    slew = (SOURCE / "scenarios" / "attitude-slew.toml").read_text()
    assert slew.count("k_p = 6.0\n") == 1
    (tmp_path / "slew.toml").write_text(slew)
    grid = tmp_path / "gains.toml"
    grid.write_text('[ensemble]\nscenario = "slew.toml"\n[[vary]]\nkey = "forcing.0.k_p"\nvalues = [3.0, 12.0]\n')
    proc = ensemble(grid, "--out", tmp_path / "gains", "--threads", "1")
    assert proc.returncode == 0, proc.stderr
    with open(tmp_path / "gains" / "members.csv", newline="") as f:
        members = list(csv.DictReader(f))
    assert [m["forcing.0.k_p"] for m in members] == ["3", "12"]
    # lgvi show names the forced members' energy error the balance it is, E - E0 - W.
    shown = subprocess.run([BINARY, "show", str(tmp_path / "gains")], capture_output=True, text=True).stdout
    assert "  max_abs_energy_error (E - E0 - W) " in shown
    for m in members:
        one = tmp_path / f"k_p-{m['forcing.0.k_p']}.toml"
        one.write_text(slew.replace("k_p = 6.0\n", f"k_p = {m['forcing.0.k_p']}.0\n"))
        out = tmp_path / one.stem
        assert subprocess.run([BINARY, "run", str(one), "--out", str(out), "-q", "--no-figures"]).returncode == 0
        final = __import__("json").loads((out / "summary.json").read_text())["final"]
        assert [float(m[k]) for k in ("qw", "qx", "qy", "qz")] == final["quaternion"]
        assert [float(m[k]) for k in ("wx", "wy", "wz")] == final["w"]
    # An index past the entries, or not a number, names the key and the form to use (exit status 2).
    for key in ("forcing.2.k_p", "forcing.first.k_p", "forcing.0", "forcing.00.k_p"):
        grid.write_text(f'[ensemble]\nscenario = "slew.toml"\n[[vary]]\nkey = "{key}"\nvalues = [3.0]\n')
        bad = ensemble(grid, "--out", tmp_path / "bad")
        assert bad.returncode == 2 and bad.stderr.count("\n") == 1, bad.stderr
        assert f'"{key}" names no table of the base scenario' in bad.stderr and "forcing.0.k_p" in bad.stderr
