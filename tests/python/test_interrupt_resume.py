"""Runs that stop and go on: SIGINT/SIGTERM stop `lgvi run` at a step boundary
with valid files, and `lgvi run --resume` continues to a trajectory
byte-identical to an uninterrupted run. Run by ctest with LGVI_BINARY set."""
import json
import os
import pathlib
import shutil
import signal
import struct
import subprocess
import time

import pytest

BINARY = os.environ.get("LGVI_BINARY")
SOURCE = pathlib.Path(os.environ.get("LGVI_SOURCE_DIR", pathlib.Path(__file__).resolve().parents[2]))
pytestmark = pytest.mark.skipif(BINARY is None, reason="LGVI_BINARY not set (run through ctest)")

STEPS = 4_000_000  # ~1 s: long enough to be interrupted mid-way


def scenario(tmp_path, every=1000):
    text = (SOURCE / "scenarios" / "paper-orbit.toml").read_text()
    text = text.replace("duration = 1000.0", f"duration = {STEPS // 100}.0").replace("every = 10", f"every = {every}")
    path = tmp_path / "long.toml"
    path.write_text(text)
    return path


def run(*args):
    return subprocess.run([BINARY, "run", *map(str, args), "--no-figures", "-q"], capture_output=True, text=True)


def line_count(path):
    try:
        return path.read_bytes().count(b"\n")
    except FileNotFoundError:
        return 0


def interrupt(args, sig, out, after=0.3):
    """Send `sig` `after` seconds once the step loop is running. The handler is
    installed after the trajectory file is opened, so a fixed delay from launch
    races with start-up on a loaded machine (the signal then kills the process
    before the handler exists, status -2). Two rows beyond those present at
    launch (header and t = 0, or the rows kept by a resume) are written from
    inside the loop, where the handler is certainly installed."""
    trajectory = pathlib.Path(out) / "trajectory.csv"
    before = line_count(trajectory)
    proc = subprocess.Popen([BINARY, "run", *map(str, args), "--no-figures", "-q"], stderr=subprocess.PIPE, text=True)
    deadline = time.monotonic() + 60
    while line_count(trajectory) < max(before, 2) + 1 and proc.poll() is None and time.monotonic() < deadline:
        time.sleep(0.005)
    time.sleep(after)
    proc.send_signal(sig)
    _, err = proc.communicate(timeout=60)
    return proc.returncode, err


def rows_are_whole(path):
    text = path.read_text()
    assert text.endswith("\n")
    lines = text.splitlines()
    assert all(line.count(",") == 20 for line in lines)
    return len(lines) - 1


@pytest.fixture(scope="module")
def uninterrupted(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("full")
    out = tmp / "full"
    proc = run(scenario(tmp), "--out", out)
    assert proc.returncode == 0, proc.stderr
    return out


@pytest.mark.parametrize("sig,status", [(signal.SIGINT, 130), (signal.SIGTERM, 143)])
def test_signal_stops_at_a_step_boundary_and_resume_is_byte_identical(tmp_path, uninterrupted, sig, status):
    out = tmp_path / "run"
    code, err = interrupt([scenario(tmp_path), "--out", out, "--checkpoint-every", 100000], sig, out)
    assert code == status, err
    assert "interrupted by" in err and "--resume" in err
    summary = json.loads((out / "summary.json").read_text())
    assert summary["completed"] is False
    assert summary["error"].startswith("interrupted by " + ("SIGINT" if sig == signal.SIGINT else "SIGTERM"))
    assert 0 < summary["steps"] < STEPS  # really stopped mid-way
    rows = rows_are_whole(out / "trajectory.csv")
    assert rows == summary["steps"] // 1000 + 1  # every 1000th step and t = 0, nothing after the stop
    assert (out / "checkpoint.bin").is_file()

    proc = run("--resume", out)
    assert proc.returncode == 0, proc.stderr
    assert (out / "trajectory.csv").read_bytes() == (uninterrupted / "trajectory.csv").read_bytes()
    resumed, full = json.loads((out / "summary.json").read_text()), json.loads((uninterrupted / "summary.json").read_text())
    assert resumed["completed"] is True
    for key in ["scenario", "steps", "max_abs_energy_error", "max_abs_quat_norm_error", "max_momentum_error",
                "solver_iterations_mean", "solver_iterations_max", "final"]:
        assert resumed[key] == full[key], key
    assert not (out / "checkpoint.bin").exists()  # complete: nothing left to resume


def test_two_interruptions_then_resume(tmp_path, uninterrupted):
    out = tmp_path / "run"
    code, _ = interrupt([scenario(tmp_path), "--out", out, "--checkpoint-every", 50000], signal.SIGINT, out, after=0.2)
    assert code == 130
    code, _ = interrupt(["--resume", out], signal.SIGINT, out, after=0.2)
    assert code in (0, 130)  # it may finish first on a fast machine
    proc = run("--resume", out) if code == 130 else None
    assert proc is None or proc.returncode == 0, proc.stderr
    assert (out / "trajectory.csv").read_bytes() == (uninterrupted / "trajectory.csv").read_bytes()


def test_resume_without_checkpoint_is_a_clear_error(tmp_path):
    out = tmp_path / "run"
    proc = run(scenario(tmp_path).parent / "nothing-here", "--out", out)
    assert proc.returncode == 2
    proc = run("--resume", tmp_path / "no-such-run")
    assert proc.returncode == 2
    assert proc.stderr.count("\n") == 1 and "scenario.toml" in proc.stderr


def test_failed_run_never_claims_success(tmp_path):
    text = (SOURCE / "tests" / "cli" / "bad" / "no-root.toml").read_text()
    path = tmp_path / "pi.toml"
    path.write_text(text)
    out = tmp_path / "run"
    proc = run(path, "--out", out)
    assert proc.returncode == 1
    summary = json.loads((out / "summary.json").read_text())
    assert summary["completed"] is False and "no root" in summary["error"]


def test_close_encounter_stops_with_step_time_and_cause(tmp_path):
    """The paper's body released at rest at x = 3 falls radially into the
    centre: with stop_at_contact, when a ball comes within its radius of it,
    the run stops, naming the step, the time and the ball; the rows up to the
    last good step stay."""
    text = (SOURCE / "scenarios" / "paper-orbit.toml").read_text()
    text = text.replace("mu = 1.0", "mu = 1.0\nstop_at_contact = true")
    text = text.replace("position = [8.0, 0.0, 0.0]", "position = [3.0, 0.0, 0.0]")
    text = text.replace("momentum = [0.0, 1.0, 0.0]", "momentum = [0.0, 0.0, 0.0]").replace("every = 10", "every = 1")
    path = tmp_path / "fall.toml"
    path.write_text(text)
    out = tmp_path / "fall"
    proc = run(path, "--out", out)
    assert proc.returncode == 1
    first = proc.stderr.splitlines()[0]
    assert "reached the centre of the central field" in first and first.startswith("lgvi: error: step ")
    step = int(first.split()[3])
    assert step > 100  # it fell for a while first
    summary = json.loads((out / "summary.json").read_text())
    assert summary["completed"] is False and summary["steps"] == step
    rows = rows_are_whole(out / "trajectory.csv")
    assert rows == step + 1  # every step up to the last good one, t = 0 included


def read_pty_run(args):
    """Runs `lgvi run ARGS` with standard error on a pseudo-terminal; returns (status, what it printed there)."""
    import pty  # noqa: F401  (os.openpty is the POSIX call; pty documents the semantics)
    master, slave = os.openpty()
    proc = subprocess.Popen([BINARY, "run", *map(str, args)], stdout=subprocess.DEVNULL, stderr=slave)
    os.close(slave)
    chunks = []
    while True:
        try:
            chunk = os.read(master, 4096)
        except OSError:  # EIO: the child closed the terminal
            break
        if not chunk:
            break
        chunks.append(chunk)
    os.close(master)
    return proc.wait(timeout=60), b"".join(chunks).decode(errors="replace")


def test_progress_line_only_on_a_terminal(tmp_path):
    code, text = read_pty_run([scenario(tmp_path), "--out", tmp_path / "tty", "--no-figures"])
    assert code == 0
    assert "steps/s" in text and "ETA" in text and f"/{STEPS}" in text
    quiet_code, quiet = read_pty_run([scenario(tmp_path), "--out", tmp_path / "tty-q", "--no-figures", "-q"])
    assert quiet_code == 0 and "steps/s" not in quiet
    piped = subprocess.run([BINARY, "run", str(scenario(tmp_path)), "--out", str(tmp_path / "pipe"), "--no-figures"],
                           capture_output=True, text=True)
    assert piped.returncode == 0 and "steps/s" not in piped.stderr and piped.stderr == ""


def read_fields(data):
    """The fields of a checkpoint of version 5: (name, type, count, payload)."""
    assert data[:8] == b"LGVICKPT" and struct.unpack_from("<q", data, 8)[0] == 5
    (count,) = struct.unpack_from("<q", data, 16)
    pos, fields = 24, []
    for _ in range(count):
        (name_size,) = struct.unpack_from("<q", data, pos)
        name = data[pos + 8:pos + 8 + name_size].decode()
        pos += 8 + name_size
        kind, n, size = struct.unpack_from("<3q", data, pos)
        pos += 24
        fields.append((name, kind, n, data[pos:pos + size]))
        pos += size
    assert pos == len(data)
    return fields


def write_fields(fields):
    out = b"LGVICKPT" + struct.pack("<qq", 5, len(fields))
    for name, kind, n, payload in fields:
        out += struct.pack("<q", len(name)) + name.encode() + struct.pack("<3q", kind, n, len(payload)) + payload
    return out


@pytest.fixture(scope="module")
def new_checkpoint(tmp_path_factory):
    """A run folder interrupted with a checkpoint of today's format."""
    tmp = tmp_path_factory.mktemp("new")
    out = tmp / "run"
    code, err = interrupt([scenario(tmp), "--out", out, "--checkpoint-every", 100000], signal.SIGINT, out)
    assert code == 130, err
    return out


def changed_copy(tmp_path, new_checkpoint, change):
    out = tmp_path / "run"
    shutil.copytree(new_checkpoint, out)
    checkpoint = out / "checkpoint.bin"
    checkpoint.write_bytes(change(checkpoint.read_bytes()))
    return out, checkpoint


def refused(out, checkpoint, message):
    """`lgvi run --resume OUT` refuses the damaged checkpoint: exit 2, one line naming the file and
    `message`, and the folder as it was (its summary still says where the run stopped), whether the
    damage is found on reading the file or by the stepper after the trajectory was reopened."""
    before = {f.name: f.read_bytes() for f in out.iterdir()}
    proc = run("--resume", out)
    assert proc.returncode == 2, proc.stderr
    assert proc.stderr.count("\n") == 1, proc.stderr
    assert str(checkpoint) in proc.stderr and message in proc.stderr, proc.stderr
    assert {f.name: f.read_bytes() for f in out.iterdir()} == before


def test_a_checkpoint_is_named_typed_fields(new_checkpoint):
    fields = read_fields((new_checkpoint / "checkpoint.bin").read_bytes())
    names = [f[0] for f in fields]
    assert len(names) == len(set(names))
    for name in ["run.step", "run.state", "statistics.energy0", "sink.position", "run.scenario_name"]:
        assert name in names, name
    assert any(name.startswith("stepper.") for name in names)  # the stepper wrote its own
    for name, kind, n, payload in fields:
        assert len(payload) == n * (1 if kind == 3 else 8), name


@pytest.mark.parametrize("name", ["future.thing", "stepper.future_thing"])
def test_an_unknown_field_is_one_clear_error(tmp_path, new_checkpoint, name):
    """A field this lgvi does not read (a newer lgvi wrote it) holds state a
    bit-identical continuation would need: refused, naming the file and the
    field, whether the run's or the stepper's."""
    out, checkpoint = changed_copy(tmp_path, new_checkpoint,
                                   lambda d: write_fields(read_fields(d) + [(name, 1, 1, struct.pack("<d", 1.0))]))
    refused(out, checkpoint, f"unknown checkpoint field '{name}'")


@pytest.mark.parametrize("missing", ["run.state", "sink.position", "stepper."])
def test_a_missing_field_is_one_clear_error(tmp_path, new_checkpoint, missing):
    fields = read_fields((new_checkpoint / "checkpoint.bin").read_bytes())
    dropped = next(f[0] for f in fields if f[0].startswith(missing))
    out, checkpoint = changed_copy(tmp_path, new_checkpoint,
                                   lambda d: write_fields([f for f in read_fields(d) if f[0] != dropped]))
    refused(out, checkpoint, f"checkpoint field '{dropped}' is missing")


def test_a_truncated_field_is_one_clear_error(tmp_path, new_checkpoint):
    data = (new_checkpoint / "checkpoint.bin").read_bytes()
    end = data.index(b"run.state") + len("run.state") + 24 + 20  # 20 bytes into the state's values
    out, checkpoint = changed_copy(tmp_path, new_checkpoint, lambda d: d[:end])
    refused(out, checkpoint, "checkpoint field 'run.state' is truncated")


def test_a_field_of_the_wrong_size_is_one_clear_error(tmp_path, new_checkpoint):
    def shorten(data):
        return write_fields([(n, k, c - 1, p[:-8]) if n == "run.step" else (n, k, c, p)
                             for n, k, c, p in read_fields(data)])
    out, checkpoint = changed_copy(tmp_path, new_checkpoint, shorten)
    refused(out, checkpoint, "checkpoint field 'run.step' holds 0 values, expected 1")


def test_a_count_whose_size_wraps_around_is_one_clear_error(tmp_path, new_checkpoint):
    """A damaged count n with n * 8 wrapping around 2^64 to the field's real byte size
    (n = 2^61 + 1: 8 bytes) is refused as damaged, not allocated."""
    def damage(data):
        return write_fields([(n, k, 2**61 + 1, p) if n == "run.step" else (n, k, c, p)
                             for n, k, c, p in read_fields(data)])
    out, checkpoint = changed_copy(tmp_path, new_checkpoint, damage)
    refused(out, checkpoint, "checkpoint field 'run.step' is damaged")


@pytest.mark.parametrize("fmt, sig", [("npz", signal.SIGINT), ("csv", signal.SIGKILL)])
def test_a_refused_resume_reopens_nothing(tmp_path, fmt, sig):
    """The stepper's fields are checked before the trajectory is reopened (reopening truncates it
    back to the checkpoint): a refused resume leaves an npz closed by SIGINT readable, and the rows
    a killed run wrote after its last checkpoint in place."""
    path = scenario(tmp_path, every=10)  # rows enough to leave the CSV writer's buffer before the kill
    path.write_text(path.read_text().replace("[output]\n", f'[output]\nformat = "{fmt}"\n', 1))
    out = tmp_path / "run"
    proc = subprocess.Popen([BINARY, "run", path, "--out", out, "--checkpoint-every", "1000000", "--no-figures",
                             "-q"], stderr=subprocess.PIPE, text=True)
    checkpoint, trajectory = out / "checkpoint.bin", out / f"trajectory.{fmt}"

    def position():  # the trajectory's length in bytes at the checkpoint
        fields = read_fields(checkpoint.read_bytes())
        return struct.unpack("<3q", next(f for f in fields if f[0] == "sink.position")[3])[1]

    # Signal once rows past the first checkpoint (step 10^6 of 4 10^6) are in the file.
    deadline = time.monotonic() + 60
    while not checkpoint.is_file() and proc.poll() is None and time.monotonic() < deadline:
        time.sleep(0.005)
    while trajectory.stat().st_size <= position() and proc.poll() is None and time.monotonic() < deadline:
        time.sleep(0.005)
    proc.send_signal(sig)
    proc.communicate(timeout=60)
    assert proc.returncode == (130 if sig == signal.SIGINT else -signal.SIGKILL)
    # The case is the one meant: the file extends past the checkpoint's position (an npz's closing
    # index, or a killed CSV's rows after the checkpoint), so reopening it would change it.
    assert trajectory.stat().st_size > position()
    fields = read_fields(checkpoint.read_bytes())
    checkpoint.write_bytes(write_fields(fields + [("stepper.future_thing", 1, 1, struct.pack("<d", 1.0))]))
    refused(out, checkpoint, "unknown checkpoint field 'stepper.future_thing'")
