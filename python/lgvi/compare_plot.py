"""Figures of `lgvi compare DIR`: work-precision diagrams and long-time
behaviour, one curve per method. Run as ``/usr/bin/python3 -m lgvi.compare_plot DIR``.

Reads DIR/work_precision.csv and DIR/long_time.csv (written by `lgvi compare`)
and writes work_precision_wall.png, work_precision_evaluations.png,
long_energy.png, long_quaternion.png and long_momentum.png into DIR.
"""
import argparse
import csv
import os
import sys


FLOOR = 1e-18  # the long-time figures draw max(|value|, FLOOR): exact zeros at the floor


def _read(path):
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


def _by_method(rows):
    out = {}
    for r in rows:
        out.setdefault(r["method"], []).append(r)
    return out


def draw_compare_figures(directory):
    """Draws the five comparison figures into `directory`; returns their paths."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import numpy as np

    wp = _by_method(_read(os.path.join(directory, "work_precision.csv")))
    lt = _by_method(_read(os.path.join(directory, "long_time.csv")))
    written = []

    def save(fig, name):
        path = os.path.join(directory, name)
        fig.tight_layout()
        fig.savefig(path, dpi=120)
        plt.close(fig)
        written.append(path)

    for xkey, xlabel, name in [("wall_seconds", "wall time (s), median and quartiles of repeats", "work_precision_wall.png"),
                               ("potential_evaluations", "potential evaluations (free body: right-hand-side stages)",
                                "work_precision_evaluations.png")]:
        fig, ax = plt.subplots(figsize=(6.5, 4.8))
        for method, rows in wp.items():
            pts = [r for r in rows
                   if r["completed"] == "true" and r["error"] not in ("null", "") and float(r["error"]) > 0]
            if pts:
                x = np.array([float(r[xkey]) for r in pts])
                y = np.array([float(r["error"]) for r in pts])
                line, = ax.loglog(x, y, "o-", label=method)
                if xkey == "wall_seconds" and "wall_seconds_q25" in pts[0]:
                    # The median of repeated runs, with its quartiles as a bar.
                    lo = x - np.array([float(r["wall_seconds_q25"]) for r in pts])
                    hi = np.array([float(r["wall_seconds_q75"]) for r in pts]) - x
                    ax.errorbar(x, y, xerr=[np.maximum(lo, 0), np.maximum(hi, 0)], fmt="none",
                                ecolor=line.get_color(), lw=0.8)
        ax.set_xlabel(xlabel)
        ax.set_ylabel("error of the final state")
        ax.set_title("Work-precision")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=8)
        save(fig, name)

    for key, label, name in [("energy_error", "|E(t) - E(0)|", "long_energy.png"),
                             ("quat_norm_error", "||q| - 1|", "long_quaternion.png"),
                             ("momentum_error", "|L(t) - L(0)|", "long_momentum.png")]:
        fig, ax = plt.subplots(figsize=(6.5, 4.8))
        for method, rows in lt.items():
            t = np.array([float(r["t"]) for r in rows])
            y = np.abs(np.array([float(r[key]) for r in rows]))
            # Exact zeros (a normalized quaternion, a conserved momentum) cannot be drawn on a log axis:
            # they are drawn at the floor, so that a curve stays a curve.
            ax.semilogy(t, np.maximum(y, FLOOR), label=method, lw=0.8)
        ax.set_xlabel("t")
        ax.set_ylabel(f"max({label}, {FLOOR:g})")
        # The adaptive LGVI's long run (+tt) has the fixed step's epsilon = e h, not its cost (comparison.md).
        adaptive = " (+tt: epsilon = e h)" if any(m.endswith("+tt") for m in lt) else ""
        ax.set_title(f"Long-time behaviour at equal cost{adaptive}: {label}")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=8)
        save(fig, name)
    return written


def main(argv=None):
    """Command line: ``python -m lgvi.compare_plot DIR``; returns the exit status."""
    parser = argparse.ArgumentParser(prog="lgvi.compare_plot", description=__doc__.splitlines()[0])
    parser.add_argument("dir")
    args = parser.parse_args(argv)
    try:
        draw_compare_figures(args.dir)
    except (OSError, KeyError, ValueError) as e:
        print(f"lgvi.compare_plot: error: {e}", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
