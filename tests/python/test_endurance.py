"""Endurance: 10^7 steps of the paper-orbit scenario with decimated output.
Peak memory must not grow with the number of steps, the relative angular
momentum error must stay at round-off and the energy error bounded.
Run by ctest with LGVI_BINARY set."""
import json
import os
import pathlib
import resource
import subprocess

import pytest

BINARY = os.environ.get("LGVI_BINARY")
SOURCE = pathlib.Path(os.environ.get("LGVI_SOURCE_DIR", pathlib.Path(__file__).resolve().parents[2]))
pytestmark = pytest.mark.skipif(BINARY is None, reason="LGVI_BINARY not set (run through ctest)")


def run_child(tmp_path, steps):
    """Runs `lgvi run` in a child process that reports its own peak RSS (KiB)."""
    text = (SOURCE / "scenarios" / "paper-orbit.toml").read_text()
    text = text.replace("duration = 1000.0", f"duration = {steps // 100}.0").replace("every = 10", "every = 10000")
    scenario = tmp_path / f"endurance-{steps}.toml"
    scenario.write_text(text)
    out = tmp_path / f"out-{steps}"
    # A fresh Python child per run, so RUSAGE_CHILDREN measures that run alone.
    code = ("import resource, subprocess, sys; "
            "r = subprocess.run(sys.argv[1:]); "
            "print(resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss); sys.exit(r.returncode)")
    proc = subprocess.run(["/usr/bin/python3", "-c", code, BINARY, "run", str(scenario), "--out", str(out),
                           "--no-figures", "-q"], capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr
    return int(proc.stdout.strip()), json.loads((out / "summary.json").read_text())


def test_ten_million_steps_flat_memory_and_invariants(tmp_path):
    rss_short, short = run_child(tmp_path, 100_000)
    rss_long, long = run_child(tmp_path, 10_000_000)
    assert long["completed"] and long["steps"] == 10_000_000
    print(f"peak RSS: 1e5 steps {rss_short} KiB, 1e7 steps {rss_long} KiB; "
          f"1e7: rel dL {long['max_relative_momentum_error']:.3e}, |q|-1 {long['max_abs_quat_norm_error']:.3e}, "
          f"dE {long['max_abs_energy_error']:.3e}")
    # Flat memory: 100x the steps may not cost more than 1 MiB of peak RSS
    # (a trajectory held in memory would be 1e7 x 21 x 8 B = 1.7 GB).
    assert rss_long - rss_short <= 1024
    # Round-off: a random walk of ~eps per step gives ~sqrt(1e7) eps ~ 1e-12.
    assert long["max_relative_momentum_error"] <= 1e-11
    assert long["max_abs_quat_norm_error"] <= 1e-11
    # Bounded energy error: no larger over 1e7 steps than 1.2x its value over the first 1e5.
    assert long["max_abs_energy_error"] <= 1.2 * short["max_abs_energy_error"]
