"""Writes the old-format checkpoint fixtures in this folder with a given lgvi
binary (the one before the named-field format: version 4 checkpoints).

    /usr/bin/python3 tests/reference/checkpoints/make_fixtures.py /path/to/old/lgvi

For every case: the scenario is run uninterrupted (its trajectory's SHA-256
and summary go to expected.json), then run again with --checkpoint-every and
stopped by SIGINT once a checkpoint is on disk; the run folder (scenario.toml,
checkpoint.bin, the trajectory so far) is kept as <case>/. The same binary's
resume of a copy is checked to reproduce the uninterrupted trajectory before
anything is kept. tests/python/test_checkpoint_fixtures.py resumes them with
the binary under test. Not run by the tests: the fixtures are committed."""
import hashlib
import json
import pathlib
import shutil
import signal
import subprocess
import sys
import tempfile
import time

HERE = pathlib.Path(__file__).resolve().parent
SCENARIOS = HERE.parents[2] / "scenarios"

# The keys of summary.json a resumed run must reproduce (the rest holds timings).
SUMMARY_KEYS = ["scenario", "steps", "completed", "max_abs_energy_error", "max_abs_quat_norm_error",
                "max_momentum_error", "solver_iterations_mean", "solver_iterations_max", "final"]


def paper_orbit(method, duration, every, extra=""):
    text = (SCENARIOS / "paper-orbit.toml").read_text()
    text = text.replace('method = "lgvi"', f'method = "{method}"{extra}')
    return text.replace("duration = 1000.0", f"duration = {duration}").replace("every = 10", f"every = {every}")


def scenario_file(name, replacements):
    text = (SCENARIOS / name).read_text()
    for old, new in replacements:
        assert old in text, (name, old)
        text = text.replace(old, new)
    return text


SATELLITE = """[body]
mass = 30.0
inertia = [[2.98, 0.0, 0.0], [0.0, 20.48, 0.0], [0.0, 0.0, 22.98]]
[potential]
kind = "central"
mu = 3.986004418e14
[initial]
position = [6878137.0, 0.0, 0.0]
quaternion = [0.9987502603949663, 0.0, 0.0, 0.04997916927067833]
velocity = [0.0, 7612.608173223869, 0.0]
omega = [0.0, 0.0, 1.1067834463349404e-3]
[integrator]
step = 10.0
duration = 1.0e7
[output]
every = 10000
"""

# case: (scenario text, steps between checkpoints)
CASES = {
    "lgvi": (paper_orbit("lgvi", 10000.0, 10000), 100000),
    "lgvi-lagrangian": (paper_orbit("lgvi-lagrangian", 10000.0, 10000), 100000),
    "so3-lgvi": (paper_orbit("so3-lgvi", 10000.0, 10000), 100000),
    "rattle-quaternion": (paper_orbit("rattle-quaternion", 10000.0, 10000), 100000),
    "lgvi-order4": (paper_orbit("lgvi", 4000.0, 4000, "\norder = 4"), 40000),
    "exact": (scenario_file("free-body-hairer.toml", [('method = "lgvi"', 'method = "exact"'),
                                                      ("duration = 500.0", "duration = 50000.0"),
                                                      ("every = 10", "every = 10000")]), 100000),
    "rk4-normalized": (paper_orbit("rk4-normalized", 10000.0, 10000), 100000),
    "attitude-slew": (scenario_file("attitude-slew.toml", [("duration = 120.0", "duration = 20000.0"),
                                                           ("every = 5", "every = 5000"),
                                                           ("[120.0, 0.0, 0.002", "[20000.0, 0.0, 0.002")]), 100000),
    "binary-asteroid": (scenario_file("binary-asteroid.toml", [("duration = 400.0", "duration = 4000.0"),
                                                               ("every = 10", "every = 4000")]), 40000),
    "satellite-gravity-gradient": (SATELLITE, 100000),
}


def run(binary, *args):
    return subprocess.run([binary, "run", *map(str, args), "--no-figures", "-q"], capture_output=True, text=True)


def sha256(path):
    return hashlib.sha256(path.read_bytes()).hexdigest()


def interrupted(binary, scenario, out, every):
    """Runs with checkpoints every `every` steps and sends SIGINT once the first is on disk."""
    for attempt in range(5):
        shutil.rmtree(out, ignore_errors=True)
        proc = subprocess.Popen([binary, "run", str(scenario), "--out", str(out), "--checkpoint-every", str(every),
                                 "--no-figures", "-q"], stderr=subprocess.PIPE, text=True)
        while not (out / "checkpoint.bin").is_file() and proc.poll() is None:
            time.sleep(0.002)
        time.sleep(0.05 * attempt)
        proc.send_signal(signal.SIGINT)
        _, err = proc.communicate(timeout=600)
        if proc.returncode == 130:
            return
        print(f"  attempt {attempt}: status {proc.returncode} ({err.strip()}), again", file=sys.stderr)
    raise SystemExit(f"{out}: could not interrupt the run")


def main():
    binary = sys.argv[1]
    expected = {}
    with tempfile.TemporaryDirectory() as tmp:
        tmp = pathlib.Path(tmp)
        for case, (text, every) in CASES.items():
            print(case, file=sys.stderr)
            scenario = tmp / f"{case}.toml"
            scenario.write_text(text)
            full = tmp / f"{case}-full"
            proc = run(binary, scenario, "--out", full)
            assert proc.returncode == 0, proc.stderr
            summary = json.loads((full / "summary.json").read_text())
            out = tmp / case
            interrupted(binary, scenario, out, every)
            check = tmp / f"{case}-check"
            shutil.copytree(out, check)
            proc = run(binary, "--resume", check)
            assert proc.returncode == 0, proc.stderr
            assert sha256(check / "trajectory.csv") == sha256(full / "trajectory.csv"), case
            kept = HERE / case
            shutil.rmtree(kept, ignore_errors=True)
            kept.mkdir()
            for name in ["scenario.toml", "checkpoint.bin", "trajectory.csv"]:
                shutil.copy(out / name, kept / name)
            stopped = json.loads((out / "summary.json").read_text())["steps"]
            expected[case] = {"trajectory_sha256": sha256(full / "trajectory.csv"),
                              "trajectory_bytes": (full / "trajectory.csv").stat().st_size,
                              "checkpoint_step": stopped,
                              "summary": {k: summary[k] for k in SUMMARY_KEYS if k in summary}}
    (HERE / "expected.json").write_text(json.dumps(expected, indent=1, sort_keys=True) + "\n")


if __name__ == "__main__":
    main()
