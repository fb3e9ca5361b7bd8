#!/usr/bin/python3
"""The adaptive LGVI against the fixed step on the paper's close pass, in one invocation:

    /usr/bin/python3 benchmarks/adaptive/close_pass.py LGVI_BINARY [--repeat 3] [--figure FILE.png]

Runs `lgvi run` on scenarios/paper.toml (p0 = (1, 0, 0), the fixed step h) for h = 0.02 ... 0.00125 and on
scenarios/paper-close-pass.toml (the same body, field and state with time_transform = "potential"), plain
for epsilon = 0.04 ... 0.005 and composed to order 4 for epsilon = 0.2 ... 0.025, over [0, 1000], each
--repeat times (--no-figures, every 1000th row written). Prints a Markdown table: the steps, the potential
evaluations (summary.json's, every one counted: the plain adaptive step evaluates twice per step, at the
midpoint for its kick and at the new state for its energy; composed to order 4, six times), max |E - E0|,
and the median of summary.json's wall_seconds (the integration loop). With --figure, max |E - E0|
against evaluations and against wall time.
"""
import argparse
import json
import pathlib
import re
import statistics
import subprocess
import sys
import tempfile

ROOT = pathlib.Path(__file__).resolve().parents[2]


def run(binary, text, folder):
    path = folder.with_suffix(".toml")
    path.write_text(text)
    proc = subprocess.run([binary, "run", str(path), "--out", str(folder), "--no-figures", "-q"],
                          capture_output=True, text=True)
    summary = json.loads((folder / "summary.json").read_text())
    return proc.returncode, summary


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("binary")
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--figure")
    args = ap.parse_args(argv)
    fixed_text = (ROOT / "scenarios" / "paper.toml").read_text()
    adaptive_text = (ROOT / "scenarios" / "paper-close-pass.toml").read_text()
    cases = [("fixed", "h", h, re.sub(r"(?m)^step = .*$", f"step = {h}", fixed_text))
             for h in (0.02, 0.01, 0.005, 0.0025, 0.00125)]
    plain = re.sub(r"(?m)^order = .*\n", "", adaptive_text)
    cases += [("adaptive", "epsilon", e, re.sub(r"(?m)^epsilon = \S+", f"epsilon = {e}", plain))
              for e in (0.04, 0.02, 0.01, 0.005)]
    cases += [("adaptive, order 4", "epsilon", e, re.sub(r"(?m)^epsilon = \S+", f"epsilon = {e}", adaptive_text))
              for e in (0.2, 0.1, 0.05, 0.025)]
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        tmp = pathlib.Path(tmp)
        for i, (kind, name, value, text) in enumerate(cases):
            text = re.sub(r"(?m)^every = .*$", "every = 1000", text)
            walls, summary = [], None
            for r in range(args.repeat):
                code, summary = run(args.binary, text, tmp / f"c{i}r{r}")
                walls.append(summary["wall_seconds"])
            rows.append(dict(kind=kind, name=name, value=value, completed=summary["completed"],
                             steps=summary["steps"], evaluations=summary["potential_evaluations"],
                             energy=summary["max_abs_energy_error"], quat=summary["max_abs_quat_norm_error"],
                             momentum=summary["max_relative_momentum_error"], wall=statistics.median(walls)))
    print("| method | step | steps | evaluations | max \\|E - E0\\| | max \\|\\|q\\| - 1\\| | max \\|dL\\|/\\|L0\\| "
          "| wall s (median) |")
    print("|---|---|---:|---:|---:|---:|---:|---:|")
    for r in rows:
        label = {"fixed": "fixed step", "adaptive": "adaptive", "adaptive, order 4": "adaptive, order 4"}[r["kind"]]
        print(f"| {label} | {r['name']} = {r['value']:g} | {r['steps']} | {r['evaluations']} | {r['energy']:.3g} | "
              f"{r['quat']:.2g} | {r['momentum']:.2g} | {r['wall']:.3f} |")
    if args.figure:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
        fig, axes = plt.subplots(1, 2, figsize=(10, 4.2), sharey=True)
        for kind, marker in (("fixed", "o-"), ("adaptive", "s-"), ("adaptive, order 4", "^-")):
            sel = [r for r in rows if r["kind"] == kind]
            axes[0].loglog([r["evaluations"] for r in sel], [r["energy"] for r in sel], marker, label=kind)
            axes[1].loglog([r["wall"] for r in sel], [r["energy"] for r in sel], marker, label=kind)
        axes[0].set(xlabel="potential evaluations", ylabel="max |E - E0| over [0, 1000]",
                    title="The paper's close pass (p0 = (1, 0, 0))")
        axes[1].set(xlabel="wall seconds (median)", title="at equal time")
        for ax in axes:
            ax.grid(True, which="both", alpha=0.3)
            ax.legend()
        fig.tight_layout()
        fig.savefig(args.figure, dpi=100)
    return 0


if __name__ == "__main__":
    sys.exit(main())
