#!/usr/bin/python3
"""The paper's experiment (Shen & Leok), from Python.

Three unit-mass balls of radius 0.1 at the corners of an equilateral triangle
of side 1, in central gravity V = -mu sum m_i / |x + R rho_i| with mu = 1;
x0 = (8, 0, 0), q0 = (1, 0, 0, 0) (scalar-first (w, x, y, z)), w0 = (1, 2, 3),
h = 0.01, t in [0, 1000]. Two initial momenta: the orbit the paper's
captions describe, p0 = (0, 1, 0), and the paper's stated p0 = (1, 0, 0)
(radial; see docs/getting-started.md). The same numbers as `lgvi run
scenarios/paper-orbit.toml` and `scenarios/paper.toml`, to the last bit.

    /usr/bin/python3 examples/paper_experiment.py [--duration T] [--out DIR]
"""

import argparse
import math
import os

import lgvi


def paper_scenario(momentum, duration=1000.0, name="paper"):
    """The paper's body, potential and initial state, with linear momentum p0 = `momentum`."""
    body = lgvi.Body.from_balls([((0.0, 0.0, 0.0), 1.0, 0.1),
                                 ((1.0, 0.0, 0.0), 1.0, 0.1),
                                 ((0.5, math.sqrt(3.0) / 2.0, 0.0), 1.0, 0.1)])
    return lgvi.Scenario(body=body, potential=lgvi.potential.central(1.0),
                         position=(8.0, 0.0, 0.0), quaternion=(1.0, 0.0, 0.0, 0.0),  # scalar first
                         momentum=momentum, w=(1.0, 2.0, 3.0),                      # w = 2 J Omega
                         step=0.01, duration=duration, every=10, name=name)


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--duration", type=float, default=1000.0, help="simulated time (default 1000)")
    parser.add_argument("--out", default=os.path.join("results", "python-paper"), help="folder for the figures")
    args = parser.parse_args(argv)

    print("| run | p0 | max |E - E0| | max ||q| - 1| | max |L - L0| / |L0| | steps/s |")
    print("|---|---|---:|---:|---:|---:|")
    for name, p0 in (("paper-orbit", (0.0, 1.0, 0.0)), ("paper", (1.0, 0.0, 0.0))):
        result = lgvi.simulate(paper_scenario(p0, args.duration, name))
        s = result.summary
        print(f"| {name} | {p0} | {s['max_abs_energy_error']:.3g} | {s['max_abs_quat_norm_error']:.2g} | "
              f"{s['max_relative_momentum_error']:.2g} | {1e9 / max(s['ns_per_step'], 1e-9):.3g} |")
        out = os.path.join(args.out, name)
        lgvi.plot.draw_figures(result, out)  # the CLI's figures, from memory
        result.save(out)                     # and a run folder like the CLI's
        print(f"|   | figures and trajectory in {out} | | | | |")


if __name__ == "__main__":
    main()
