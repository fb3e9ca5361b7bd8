#!/usr/bin/python3
"""Energy error against time for several step sizes, on the paper's orbit.

A variational integrator keeps the energy error bounded (no drift) and, for
this second-order method, proportional to h^2: halving h divides max |E - E0|
by about 4. Writes energy_error_vs_step.png: above, the envelope of
|E(t) - E(0)| (its maximum over windows of 1% of the run), log scale; below,
(E(t) - E(0)) / h^2, where the curves of all step sizes coincide.

    /usr/bin/python3 examples/step_size_study.py [--duration T] [--out DIR]
"""

import argparse
import os
import pathlib

import numpy as np

import lgvi

SCENARIO = pathlib.Path(__file__).resolve().parent.parent / "scenarios" / "paper-orbit.toml"
STEPS = (0.04, 0.02, 0.01, 0.005)


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--duration", type=float, default=250.0, help="simulated time (default 250, ~2 orbits)")
    parser.add_argument("--out", default=os.path.join("results", "step-size-study"), help="output folder")
    args = parser.parse_args(argv)
    base = lgvi.Scenario.from_toml(SCENARIO)

    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (ax, ax2) = plt.subplots(2, 1, figsize=(7.0, 7.0), sharex=True)
    print("| h | steps | max |E - E0| | ratio to the previous h | (h / h_prev)^2 |")
    print("|---:|---:|---:|---:|---:|")
    previous = None
    for h in STEPS:
        # About 1000 rows per run, whatever h.
        every = max(1, int(round(args.duration / h / 1000)))
        result = lgvi.simulate(base.replace(step=h, duration=args.duration, every=every))
        err = result.summary["max_abs_energy_error"]
        ratio = "" if previous is None else f"{err / previous[1]:.3f}"
        expected = "" if previous is None else f"{(h / previous[0]) ** 2:.3f}"
        print(f"| {h:g} | {result.summary['steps']} | {err:.3e} | {ratio} | {expected} |")
        window = max(1, len(result) // 100)
        n = len(result) // window * window
        envelope = np.abs(result.energy_error[:n]).reshape(-1, window).max(axis=1)
        ax.plot(result.t[:n:window], envelope, lw=1.0, label=f"h = {h:g}")
        ax2.plot(result.t, result.energy_error / h ** 2, lw=0.6, label=f"h = {h:g}")
        previous = (h, err)
    ax.set_yscale("log")
    ax.set(title="Energy error of the quaternion LGVI on the paper's orbit",
           ylabel="max |E - E0| over 1% windows")
    ax.legend(loc="lower right", fontsize="small")
    ax2.set(xlabel="t", ylabel="(E(t) - E(0)) / h^2")
    os.makedirs(args.out, exist_ok=True)
    path = os.path.join(args.out, "energy_error_vs_step.png")
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    print(f"\nwrote {path}")


if __name__ == "__main__":
    main()
