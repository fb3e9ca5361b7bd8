"""`lgvi compare` end to end on the Manchester & Peck free body, whose exact
flow is the reference: every method's observed order, the equal-cost long
runs, the tables and the figures. Run by ctest with LGVI_BINARY set."""
import csv
import os
import pathlib
import subprocess

import pytest

BINARY = os.environ.get("LGVI_BINARY")
SOURCE = pathlib.Path(os.environ.get("LGVI_SOURCE_DIR", pathlib.Path(__file__).resolve().parents[2]))
pytestmark = pytest.mark.skipif(BINARY is None, reason="LGVI_BINARY not set (run through ctest)")

NOMINAL = {"lgvi": 2, "lgvi-lagrangian": 2, "so3-lgvi": 2, "rattle-quaternion": 2, "rk4-normalized": 4,
           "euler-exp": 1, "no-squish": 2, "splitting-dlm": 2}


@pytest.fixture(scope="module")
def comparison(tmp_path_factory):
    out = tmp_path_factory.mktemp("compare")
    methods = ",".join(list(NOMINAL) + ["exact"])
    proc = subprocess.run([BINARY, "compare", str(SOURCE / "scenarios" / "free-body-manchester-peck.toml"),
                           "--methods", methods, "--out", str(out), "--ladder", "4", "--error-time", "10",
                           "--long-steps", "20000", "--timing-budget", "0.02", "-q"], capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr
    with open(out / "comparison.csv", newline="") as f:
        return out, {r["method"]: r for r in csv.DictReader(f)}


def test_observed_orders_against_the_exact_flow(comparison):
    _, rows = comparison
    for method, order in NOMINAL.items():
        # h = 0.1 ... 0.0125 to t = 10 is in the asymptotic regime: the ratio of
        # the last two errors is 2^p to within a few percent.
        assert abs(float(rows[method]["observed_order"]) - order) < 0.1, (method, rows[method]["observed_order"])
    assert float(rows["exact"]["error_at_h"]) <= 1e-13  # the reference itself, at t = k h


def test_equal_cost_long_runs(comparison):
    _, rows = comparison
    assert float(rows["rk4-normalized"]["long_h"]) == pytest.approx(4 * 0.1)  # 4 evaluations per step
    assert float(rows["lgvi"]["long_h"]) == pytest.approx(0.1)
    # The free body's LGVI conserves the spatial angular momentum to round-off
    # (discrete Noether), the normalized RK4 does not.
    assert float(rows["lgvi"]["long_max_relative_momentum_error"]) < 1e-12
    assert float(rows["rk4-normalized"]["long_max_relative_momentum_error"]) > 1e-6


def test_tables_and_figures_are_written(comparison):
    out, _ = comparison
    md = (out / "comparison.md").read_text()
    assert "| lgvi |" in md and "Least cost" in md
    for name in ["work_precision.csv", "long_time.csv", "work_precision_wall.png", "work_precision_evaluations.png",
                 "long_energy.png", "long_quaternion.png", "long_momentum.png"]:
        assert (out / name).stat().st_size > 500, name


def test_unknown_method_is_a_clear_error(tmp_path):
    proc = subprocess.run([BINARY, "compare", str(SOURCE / "scenarios" / "paper-orbit.toml"), "--methods",
                           "lgvi,verlet", "--out", str(tmp_path)], capture_output=True, text=True)
    assert proc.returncode == 2 and proc.stderr.count("\n") == 1 and "verlet" in proc.stderr
    proc = subprocess.run([BINARY, "compare", str(SOURCE / "scenarios" / "paper-orbit.toml"), "--methods",
                           "exact", "--out", str(tmp_path)], capture_output=True, text=True)
    assert proc.returncode == 2 and "free body" in proc.stderr


def test_composed_orders_in_compare(tmp_path):
    # NAME:ORDER composes a symmetric method: observed orders 4 and 6 on the
    # free body against the exact flow (h = 0.2 ... 0.05 to t = 8: asymptotic,
    # errors 1e-6 ... 1e-11, tests/test_composition.cpp), 5 and 9 evaluations per step.
    proc = subprocess.run([BINARY, "compare", str(SOURCE / "scenarios" / "free-body-manchester-peck.toml"),
                           "--methods", "lgvi:4,no-squish:6", "--out", str(tmp_path / "c"), "--ladder", "3",
                           "--ladder-from", "0.2", "--error-time", "8", "--long-steps", "1000", "-q",
                           "--timing-budget", "0",
                           "--no-figures"], capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr
    with open(tmp_path / "c" / "comparison.csv", newline="") as f:
        rows = {r["method"]: r for r in csv.DictReader(f)}
    assert abs(float(rows["lgvi:4"]["observed_order"]) - 4) < 0.2
    assert abs(float(rows["no-squish:6"]["observed_order"]) - 6) < 0.2
    assert float(rows["lgvi:4"]["long_h"]) == pytest.approx(5 * 0.1)  # equal cost: 5 evaluations per step
    for bad, message in (("rk4-normalized:4", "cannot be composed"), ("lgvi:3", "2, 4, 6 or 8")):
        proc = subprocess.run([BINARY, "compare", str(SOURCE / "scenarios" / "paper-orbit.toml"), "--methods", bad,
                               "--out", str(tmp_path / "bad")], capture_output=True, text=True)
        assert proc.returncode == 2 and proc.stderr.count("\n") == 1 and message in proc.stderr, proc.stderr


def test_timings_are_repeated_medians_with_quartiles(comparison):
    out, rows = comparison
    with open(out / "work_precision.csv", newline="") as f:
        points = list(csv.DictReader(f))
    for p in points:
        # At least 3 repeats, and until they add up to the budget (0.02 s here): the sum of the repeats is
        # at least about repeats x the first quartile.
        n = int(p["timing_repeats"])
        assert n >= 3, p
        q25, median, q75 = (float(p[k]) for k in ("wall_seconds_q25", "wall_seconds", "wall_seconds_q75"))
        assert 0 < q25 <= median <= q75, p
    for r in rows.values():
        assert float(r["ns_per_step_q25"]) <= float(r["ns_per_step"]) <= float(r["ns_per_step_q75"])
        assert r["vs_lgvi_within_noise"] in ("true", "false")
    assert rows["lgvi"]["vs_lgvi_within_noise"] == "false"  # not ranked against itself


def test_error_parts_do_not_mix_units(comparison):
    out, rows = comparison
    with open(out / "work_precision.csv", newline="") as f:
        points = [p for p in csv.DictReader(f) if p["method"] == "lgvi"]
    for p in points:
        parts = [float(p[k]) for k in ("position_error", "attitude_error_rad", "momentum_error",
                                       "angular_velocity_error")]
        # The error is the largest part, exactly (the same doubles).
        assert float(p["error"]) == max(parts)
        # The free body rests at the origin: x and p stay 0 exactly (absolute errors, the scale is 0).
        assert parts[0] == 0 and parts[2] == 0
    # Attitude angle and |R - R_ref|_F = 2 sqrt(2) sin(angle / 2) agree to first order: the attitude error at
    # the finest step is a small angle, second order in h (ratio 4 per halving, to a few percent).
    a = [float(p["attitude_error_rad"]) for p in points]
    assert all(3.8 < a[j] / a[j + 1] < 4.2 for j in range(len(a) - 1)), a


def test_free_body_cost_is_wall_time_and_exact_is_not_ranked(comparison):
    out, _ = comparison
    md = (out / "comparison.md").read_text()
    table = md[md.index("Least cost"):]
    assert "wall time only" in table and "fewest potential evaluations" not in table
    assert "exact" not in table.split("\n", 1)[1].replace("the exact flow", "")  # the reference, not a contender
    assert "| exact |" in md  # but its errors are listed
    assert "stages/step" in md


def test_output_folder_is_printed_and_not_overwritten(tmp_path):
    args = [BINARY, "compare", str(SOURCE / "scenarios" / "free-body-manchester-peck.toml"), "--methods", "lgvi",
            "--ladder", "2", "--error-time", "1", "--long-steps", "100", "--no-figures", "--timing-budget", "0"]
    out = tmp_path / "c"
    proc = subprocess.run(args + ["--out", str(out)], capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.rstrip().endswith(f"lgvi compare: output in {out}")
    again = subprocess.run(args + ["--out", str(out)], capture_output=True, text=True)
    assert again.returncode == 2 and again.stderr.count("\n") == 1 and "--force" in again.stderr, again.stderr
    assert subprocess.run(args + ["--out", str(out), "--force", "-q"], capture_output=True).returncode == 0
    helptext = subprocess.run([BINARY, "compare", "--help"], capture_output=True, text=True).stdout
    assert "Default: lgvi,lgvi-lagrangian" in helptext and "--force" in helptext and "--timing-budget" in helptext
