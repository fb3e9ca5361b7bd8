#!/usr/bin/python3
"""Writes the outputs of every bundled single-body scenario under every method, solver and
trajectory format to a folder, in a form that can be compared byte for byte
between two builds (a refactor must leave them unchanged):

    scripts/output_snapshot.py BUILD_BEFORE/lgvi /tmp/before
    scripts/output_snapshot.py build/lgvi /tmp/after
    diff -r /tmp/before /tmp/after

With --all, also every many-body ([[bodies]]) and forced ([[forcing]])
scenario, under every method and in every trajectory format (xyz and vtk
and lammps-dump too): the set a refactor of the library's internals is compared on (tests/reference holds
hashes of the default set only, which tests/python/test_single_body_outputs.py
checks).

Each run is shortened to 2000 steps (every 10th row written). What varies from
run to run by nature -- the wall-clock fields of the summary -- is blanked;
npz and HDF5 files are unpacked into their arrays' raw bytes and their text
attributes (with the summary blanked likewise), so the comparison is exact
everywhere else.
"""
import io
import json
import pathlib
import re
import subprocess
import sys
import zipfile

ROOT = pathlib.Path(__file__).resolve().parent.parent
METHODS = ["lgvi", "lgvi-lagrangian", "so3-lgvi", "rattle-quaternion", "rk4-normalized", "euler-exp",
           "no-squish", "splitting-dlm", "exact"]
WALL = re.compile(r'"(wall_seconds|ns_per_step)": [^,\n}]*')


def blank_wall(text):
    return WALL.sub(lambda m: f'"{m.group(1)}": "(blanked)"', text)


def variants(path, every_format=False):
    text = path.read_text()
    free = 'kind = "none"' in text
    formats = ("csv", "npz", "hdf5", "xyz", "vtk", "lammps-dump") if every_format else ("csv", "npz", "hdf5")
    if re.search(r'^time_transform = "potential"', text, re.M):  # the adaptive step: lgvi's Hamiltonian form only
        for fmt in formats:
            yield "lgvi", None, fmt
        return
    for method in METHODS:
        if method == "exact" and not free:
            continue
        solvers = ["newton", "newton-exp", "broyden"] if method == "lgvi" else [None]
        for solver in solvers:
            for fmt in formats:
                if fmt != "csv" and (solver not in (None, "newton") or method not in ("lgvi", "rk4-normalized")):
                    continue
                yield method, solver, fmt


def scenario_text(text, method, solver, fmt):
    # (An adaptive scenario's fictitious step epsilon, under [integrator]: 2000 of them, or more steps where
    # they shrink. Not [interaction]'s epsilon, which Lennard-Jones scenarios have.)
    adaptive = re.search(r'^time_transform = "potential"', text, re.M)
    key = "epsilon" if adaptive else "step"
    integrator = text[text.index("[integrator]"):]
    step = float(re.search(rf"^{key} = ([0-9.eE+-]+)", integrator, re.M).group(1))
    # Every variant names its method: replaced where the scenario has a method line, added to
    # [integrator] where it has none (the default, lgvi, would otherwise run under every name).
    if re.search(r'^method = "[^"]*"', text, flags=re.M):
        text = re.sub(r'^method = "[^"]*"', f'method = "{method}"', text, flags=re.M)
    else:
        text = text.replace("[integrator]\n", f'[integrator]\nmethod = "{method}"\n', 1)
    text = re.sub(r"^duration = [0-9.eE+-]+", f"duration = {2000 * step!r}", text, flags=re.M)
    text = re.sub(r'^solver = "[^"]*"\n', "", text, flags=re.M)
    if solver:
        text = text.replace("[integrator]\n", f'[integrator]\nsolver = "{solver}"\n', 1)
    text = re.sub(r"^every = \d+", "every = 10", text, flags=re.M)
    text = text.replace("[output]\n", f'[output]\nformat = "{fmt}"\n', 1)
    return text


def unpack(run, dest):
    for f in sorted(run.iterdir()):
        if f.name == "summary.json":
            (dest / f.name).write_text(blank_wall(f.read_text()))
        elif f.suffix == ".npz":
            with zipfile.ZipFile(f) as z:
                for name in z.namelist():
                    data = z.read(name)
                    if name == "summary.npy":  # a numpy string: compare its text
                        import numpy
                        data = blank_wall(str(numpy.load(io.BytesIO(data)))).encode()
                    (dest / f"{f.name}.{name}").write_bytes(data)
        elif f.suffix == ".h5":
            import h5py
            with h5py.File(f, "r") as h:
                (dest / f"{f.name}.trajectory.bin").write_bytes(h["trajectory"][()].tobytes())
                attrs = {k: blank_wall(str(v)) for k, v in h["trajectory"].attrs.items()}
                attrs.update({"/" + k: blank_wall(str(v)) for k, v in h.attrs.items()})
                (dest / f"{f.name}.attrs.txt").write_text(json.dumps(attrs, indent=1, sort_keys=True))
        elif f.suffix in (".csv", ".toml") or (ALL and f.is_file() and f.suffix not in (".png", ".json")):
            (dest / f.name).write_bytes(f.read_bytes())
        elif ALL and f.is_dir():
            sub = dest / f.name
            sub.mkdir(exist_ok=True)
            unpack(f, sub)


ALL = False


def main():
    global ALL
    args = sys.argv[1:]
    ALL = "--all" in args
    args = [a for a in args if a != "--all"]
    if len(args) != 2:
        sys.exit("usage: output_snapshot.py [--all] LGVI_BINARY OUT_DIR")
    binary, out = pathlib.Path(args[0]).resolve(), pathlib.Path(args[1])
    out.mkdir(parents=True, exist_ok=True)
    sources = sorted((ROOT / "scenarios").glob("*.toml")) + sorted((ROOT / "tests/cli/good").glob("*.toml"))
    # Single-body scenarios: the outputs that existed before the many-body
    # redesign (tests/reference/single_body_outputs.sha256); forced scenarios
    # ([[forcing]], added later) have no such outputs.
    if not ALL:
        sources = [s for s in sources if not any(table in s.read_text() for table in ("[[bodies]]", "[[forcing]]",
                                                                                       "[import]"))]
    work = out / "_work"
    work.mkdir(exist_ok=True)
    for path in sources:
        for method, solver, fmt in variants(path, every_format=ALL):
            name = f"{path.stem}__{method}{'__' + solver if solver else ''}__{fmt}"
            scen = work / f"{name}.toml"
            # (An [import]'s data file is relative to the scenario: made absolute for the copy in work/.)
            text = re.sub(r'^lammps_data = "([^"]*)"', lambda m: f'lammps_data = "{(path.parent / m.group(1)).resolve()}"',
                          path.read_text(), flags=re.M)
            scen.write_text(scenario_text(text, method, solver, fmt))
            run = work / name
            proc = subprocess.run([str(binary), "run", str(scen), "--out", str(run), "--force", "--no-figures", "-q"],
                                  capture_output=True, text=True)
            dest = out / name
            dest.mkdir(exist_ok=True)
            (dest / "exit.txt").write_text(f"{proc.returncode}\n" + proc.stderr.replace(str(run), "RUN"))
            if run.exists():
                unpack(run, dest)
    import shutil
    shutil.rmtree(work)


if __name__ == "__main__":
    main()
