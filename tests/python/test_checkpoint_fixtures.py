"""Checkpoints written before the named-field format (version 4, by the lgvi
before it: tests/reference/checkpoints/make_fixtures.py) still resume, to the
trajectory that lgvi wrote without an interruption, byte for byte. One
fixture per kind of stepper state: the Hamiltonian and Lagrangian forms, SO(3),
RATTLE, a composition, the exact flow, an explicit method, a forcing with a
sampled controller, many bodies. Run by ctest with LGVI_BINARY set."""
import hashlib
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
FIXTURES = SOURCE / "tests" / "reference" / "checkpoints"
EXPECTED = json.loads((FIXTURES / "expected.json").read_text())
pytestmark = pytest.mark.skipif(BINARY is None, reason="LGVI_BINARY not set (run through ctest)")


def run(*args):
    return subprocess.run([BINARY, "run", *map(str, args), "--no-figures", "-q"], capture_output=True, text=True)


def fixture_copy(tmp_path, case):
    out = tmp_path / case
    shutil.copytree(FIXTURES / case, out)
    return out


def version(path):
    data = path.read_bytes()
    assert data[:8] == b"LGVICKPT"
    return struct.unpack_from("<q", data, 8)[0]


@pytest.mark.parametrize("case", sorted(EXPECTED))
def test_an_old_checkpoint_resumes_to_the_old_uninterrupted_trajectory(tmp_path, case):
    expected = EXPECTED[case]
    out = fixture_copy(tmp_path, case)
    # The fixture is an old-format file stopped mid-way: otherwise this test
    # would not exercise the old reader or the resume at all.
    assert version(out / "checkpoint.bin") == 4
    assert 0 < expected["checkpoint_step"] < expected["summary"]["steps"]
    proc = run("--resume", out)
    assert proc.returncode == 0, proc.stderr
    trajectory = (out / "trajectory.csv").read_bytes()
    assert len(trajectory) == expected["trajectory_bytes"]
    assert hashlib.sha256(trajectory).hexdigest() == expected["trajectory_sha256"]
    summary = json.loads((out / "summary.json").read_text())
    for key, value in expected["summary"].items():
        assert summary[key] == value, key
    assert not (out / "checkpoint.bin").exists()  # complete: nothing left to resume


def legacy_as_version_2(data):
    """A version-4 file of one body rewritten in the layout of version 2: 9
    statistics (no linear momentum, no rotation statistics) and no contact
    trailer. The layout: magic, version, k, then length-prefixed arrays of
    doubles (state, stepper, statistics), then 11 int64 and the name."""
    pos = 24
    arrays = []
    for _ in range(3):
        (n,) = struct.unpack_from("<q", data, pos)
        arrays.append(list(struct.unpack_from(f"<{n}d", data, pos + 8)))
        pos += 8 + 8 * n
    ints = struct.unpack_from("<10q", data, pos)
    pos += 80
    (name_size,) = struct.unpack_from("<q", data, pos)
    name = data[pos + 8:pos + 8 + name_size]
    state, stepper, stats = arrays
    assert len(state) == 13 and len(stats) == 23
    out = data[:8] + struct.pack("<qq", 2, struct.unpack_from("<q", data, 16)[0])
    for a in (state, stepper, stats[:9]):
        out += struct.pack(f"<q{len(a)}d", len(a), *a)
    return out + struct.pack("<10q", *ints) + struct.pack("<q", name_size) + name


def test_a_version_2_checkpoint_resumes(tmp_path):
    """Version 2 (one body, before the linear momentum statistics and contact
    episodes) resumes to the same trajectory: the rows depend on E0 and L0,
    which it holds."""
    out = fixture_copy(tmp_path, "lgvi")
    checkpoint = out / "checkpoint.bin"
    checkpoint.write_bytes(legacy_as_version_2(checkpoint.read_bytes()))
    assert version(checkpoint) == 2
    proc = run("--resume", out)
    assert proc.returncode == 0, proc.stderr
    assert hashlib.sha256((out / "trajectory.csv").read_bytes()).hexdigest() == EXPECTED["lgvi"]["trajectory_sha256"]
    summary = json.loads((out / "summary.json").read_text())
    assert summary["completed"] is True and summary["steps"] == EXPECTED["lgvi"]["summary"]["steps"]


def test_a_version_3_checkpoint_does_not_resume_with_the_gravity_gradient_model(tmp_path):
    """Version 3 was written by an lgvi that ran a body of mass + inertia in a
    central field as a point mass: refused in one line naming the fix; with
    model = "point" in the run's scenario copy it resumes."""
    out = fixture_copy(tmp_path, "satellite-gravity-gradient")
    checkpoint = out / "checkpoint.bin"
    data = bytearray(checkpoint.read_bytes())
    data[8:16] = struct.pack("<q", 3)
    checkpoint.write_bytes(bytes(data))
    proc = run("--resume", out)
    assert proc.returncode == 2
    assert proc.stderr.count("\n") == 1 and "gravity-gradient" in proc.stderr
    assert 'add model = "point" to [potential]' in proc.stderr.lower()
    scenario_copy = out / "scenario.toml"
    scenario_copy.write_text(scenario_copy.read_text().replace('kind = "central"', 'kind = "central"\nmodel = "point"'))
    proc = run("--resume", out)
    assert proc.returncode == 0, proc.stderr
    assert json.loads((out / "summary.json").read_text())["completed"] is True


def test_a_truncated_old_checkpoint_is_one_clear_error(tmp_path):
    out = fixture_copy(tmp_path, "binary-asteroid")
    checkpoint = out / "checkpoint.bin"
    checkpoint.write_bytes(checkpoint.read_bytes()[:100])
    proc = run("--resume", out)
    assert proc.returncode == 2
    assert proc.stderr.count("\n") == 1 and str(checkpoint) in proc.stderr and "truncated" in proc.stderr


@pytest.mark.parametrize("case", sorted(EXPECTED))
def test_resumed_from_an_old_checkpoint_then_from_a_new_one(tmp_path, case):
    """The old checkpoint resumed, stopped again once this lgvi has written
    its own checkpoint (named fields, version 5), and resumed from that: the
    same bytes as the old lgvi's uninterrupted run. This covers every
    stepper's own fields (predictors, carries, the Lagrangian form's next
    configuration, SO(3)'s R, the exact flow's start, composition stages,
    forcing and sampled controllers, many bodies)."""
    out = fixture_copy(tmp_path, case)
    checkpoint = out / "checkpoint.bin"
    proc = subprocess.Popen([BINARY, "run", "--resume", str(out), "--checkpoint-every", "1000", "--no-figures", "-q"],
                            stderr=subprocess.PIPE, text=True)
    while proc.poll() is None:
        try:
            if version(checkpoint) == 5:
                break
        except (FileNotFoundError, AssertionError, struct.error):
            pass
        time.sleep(0.001)
    proc.send_signal(signal.SIGINT)
    _, err = proc.communicate(timeout=600)
    # Finished before the signal: the new format was not exercised (the
    # fixture's runs are long enough that this does not happen).
    assert proc.returncode == 130, err
    assert version(checkpoint) == 5
    proc = run("--resume", out)
    assert proc.returncode == 0, proc.stderr
    assert hashlib.sha256((out / "trajectory.csv").read_bytes()).hexdigest() == EXPECTED[case]["trajectory_sha256"]
