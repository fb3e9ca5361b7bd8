#!/usr/bin/python3
"""Generates the reference tables of the documentation (run by scripts/docs.sh before Sphinx):

  OUT/scenario-keys.md  every key of a scenario file and of a sweep file, from the reader itself: the
                        key lists of its `only_keys(...)` checks in src/app/scenario.cpp and src/app/ensemble.cpp
                        (the lists behind "unknown key; allowed here: ..."), the interaction kinds and
                        their keys from the compiled module (lgvi._core.INTERACTION_KEYS, read from
                        src/app/interactions/registry.cpp), the names of methods, solvers and formats from
                        lgvi._core (METHODS, SOLVERS, FORMATS, FORMAT_FILES);
  OUT/commands.md       `lgvi --help` and `lgvi COMMAND --help` of the built binary;
  OUT/cpp.md            the C++ API page: what each public header declares (doxygen's XML, which docs.sh
                        writes first), then the namespace through breathe;
  OUT/outputs.md        the trajectory columns (lgvi._core's headers), the keys of summary.json, and the
                        files and columns of a run folder, a comparison and an ensemble, read from real
                        (short) runs of the built binary.

Each key found in the reader needs a line in DESCRIPTIONS below, and each line there a key in the reader:
a key added to the reader without a description, or a description left for a removed key, stops the
build naming it. So the reference cannot list a key the reader does not take, or miss one it takes.

Usage: scripts/docs_reference.py BUILD_DIR OUT_DIR
"""

import json
import pathlib
import re
import subprocess
import sys
import tempfile

ROOT = pathlib.Path(__file__).resolve().parents[1]

# One line per key: "table.key" as the reader names it (prefix of its messages, with [i] dropped).
DESCRIPTIONS = {
    # root
    ".body": "table: the one body of a single-body scenario (with [initial])",
    ".bodies": "array of tables [[bodies]]: the bodies of a many-body scenario (instead of [body] + [initial])",
    ".potential": "table: the external field",
    ".initial": "table: the single body's initial state",
    ".interaction": "table: the mutual interaction between bodies",
    ".integrator": "table: method, step, duration and solver",
    ".output": "table: what is written",
    ".run": "table: threads and contact checks",
    ".forcing": "array of tables [[forcing]]: forces and torques no potential gives",
    ".box": "table: a periodic (or bounded) box for [[bodies]] (default: free space)",
    ".import": "table: the bodies, initial state and box of a LAMMPS data file, in place of [[bodies]] and [box]",
    # [body]
    "body.mass": "number > 0: total mass (with inertia, or with shape)",
    "body.inertia": "3x3 array: the inertia J about the centre of mass, body axes (symmetric positive semi-definite; a zero moment: a linear body)",
    "body.ball": "array of tables [[body.ball]]: uniform balls making up the body (mass and inertia from them)",
    "body.physical": "boolean, default true: false waives the triangle inequality J1 + J2 >= J3",
    "body.radius": "number: with mass + inertia, a bounding sphere's radius (contact checks); with shape = \"sphere\", its radius",
    "body.shape": "\"sphere\" | \"ellipsoid\": a uniform solid shape instead of mass + inertia",
    "body.semi_axes": "[a, b, c]: the ellipsoid's semi-axes along the body axes",
    "body.density": "number > 0: the shape's density (instead of mass)",
    # balls
    "body.wheel": "array of tables [[body.wheel]]: reaction wheels (the body a gyrostat; its inertia is then the whole body's with the wheels locked)",
    "body.wheel.axis": "[x, y, z]: the wheel's spin axis in body axes, a unit vector",
    "body.wheel.inertia": "number > 0: the wheel's moment j about its axis (below the body's moment about that axis)",
    "body.wheel.speed": "number: the wheel's initial speed relative to the body, rad/s (required; 0 at rest)",
    "body.wheel.max_torque": "number > 0, optional: the motor torque is clipped to +-max_torque",
    "body.wheel.max_speed": "number > 0, optional: a wheel at this speed relative to the body gets no torque that would speed it up",
    "body.wheel.name": "string, default wheel0, wheel1, ...: names the wheel in [[forcing]] and its trajectory columns NAME.speed, NAME.momentum, NAME.torque",
    "body.ball.position": "[x, y, z]: the ball's centre, body frame (the centre of mass is moved to the origin)",
    "body.ball.mass": "number > 0: the ball's mass",
    "body.ball.radius": "number >= 0: the ball's radius (0: a point mass)",
    "body.ball.type": "integer in [1, 256], default 1: the site's type, which picks [[interaction.pair]]'s coefficients",
    # [[bodies]]
    "bodies.name": "string, optional, unique: the body's name (default body0, body1, ...; a block: NAME0, NAME1, ...)",
    "bodies.mass": "as body.mass",
    "bodies.inertia": "as body.inertia",
    "bodies.ball": "array of tables [[bodies.ball]]: as [[body.ball]]",
    "bodies.wheel": "array of tables [[bodies.wheel]]: the body's reaction wheels, as [[body.wheel]] (not on a block with count)",
    "bodies.physical": "as body.physical",
    "bodies.radius": "as body.radius",
    "bodies.shape": "as body.shape",
    "bodies.semi_axes": "as body.semi_axes",
    "bodies.density": "as body.density",
    "bodies.position": "[x, y, z]: the centre of mass (a block: the lattice's first site)",
    "bodies.quaternion": "[qw, qx, qy, qz]: the attitude, scalar first (a block: every body's)",
    "bodies.momentum": "[px, py, pz]: linear momentum (or velocity)",
    "bodies.velocity": "[vx, vy, vz]: velocity of the centre of mass (or momentum)",
    "bodies.w": "[w1, w2, w3]: the paper's w = 2 J Omega (or omega)",
    "bodies.omega": "[O1, O2, O3]: body angular velocity (or w)",
    "bodies.count": "integer: a block of this many identical bodies on a cubic lattice",
    "bodies.spacing": "number: the block's lattice spacing",
    "bodies.seed": "integer: the block's random attitudes and velocities (or quaternion for all)",
    "bodies.temperature": "number: kT of the block's random momenta; total momentum removed",
    # [potential]
    "potential.kind": "\"none\" | \"central\" | \"uniform\" | \"heavy-top\"",
    "potential.mu": "central: mu in V = -mu sum_i m_i / |x + R rho_i|",
    "potential.stop_at_contact": "central: stop when a ball's centre comes within its radius of the source",
    "potential.j2": "central: the source's J2 (oblateness)",
    "potential.reference_radius": "central: R of the J2 term (needed with j2; the altitude's reference)",
    "potential.pole": "central: the source's axis of symmetry (unit vector, default z)",
    "potential.model": "central: \"extended\" (default) | \"point\" (every body a point mass: no torque)",
    "potential.g": "uniform, heavy-top: the field g (V = -m g . x; heavy top: V = -m g . (R chi))",
    "potential.pivot_to_com": "heavy-top: chi, from the pivot to the centre of mass, body frame",
    # [initial]
    "initial.position": "[x, y, z]: the centre of mass",
    "initial.quaternion": "[qw, qx, qy, qz]: scalar first; |q| within 1e-6 of 1, then normalized",
    "initial.momentum": "[px, py, pz] (or velocity; exactly one)",
    "initial.velocity": "[vx, vy, vz] (or momentum; exactly one)",
    "initial.w": "[w1, w2, w3]: the paper's w = 2 J Omega (or omega; exactly one)",
    "initial.omega": "[O1, O2, O3]: the body angular velocity (or w)",
    "initial.orbit": "inline table: the orbit, instead of position + momentum (central potential only)",
    "initial.attitude": "inline table: the attitude in the LVLH frame, instead of quaternion",
    "initial.orbit.altitude": "semi-major axis minus potential.reference_radius (or radius; exactly one)",
    "initial.orbit.radius": "semi-major axis a (or altitude)",
    "initial.orbit.eccentricity": "in [0, 1), default 0",
    "initial.orbit.inclination": "degrees, required",
    "initial.orbit.raan": "degrees, default 0: right ascension of the ascending node, from the x axis",
    "initial.orbit.arg_periapsis": "degrees, default 0",
    "initial.orbit.true_anomaly": "degrees, default 0",
    "initial.attitude.frame": "\"lvlh\"",
    "initial.attitude.roll": "degrees, default 0 (about the along-track axis, after pitch)",
    "initial.attitude.pitch": "degrees, default 0 (about the orbit normal, first)",
    "initial.attitude.yaw": "degrees, default 0 (about the radial axis, last)",
    "initial.attitude.rate": "\"orbit\": turn with the LVLH frame (or give initial.w / omega)",
    "initial.attitude.error": "[qw, qx, qy, qz], default none: a body-frame rotation after roll, pitch and yaw "
                              "(an ensemble's attitude_error_deg writes it); rate = \"orbit\" turns with it",
    # [integrator]
    "integrator.method": "one of the methods below (default \"lgvi\")",
    "integrator.solver": "one of the solvers below (default \"newton\")",
    "integrator.step": "number > 0: the step h",
    "integrator.duration": "number >= 0: runs ceil(duration/step) steps (adaptive: until the first step that reaches it)",
    "integrator.tolerance": "the solver's relative tolerance (default 4 eps)",
    "integrator.max_iterations": "the solver's iteration limit (default 50)",
    "integrator.predictor_order": "0 ... 3: initial guess, 0 = previous step's f, 3 = cubic extrapolation (default)",
    "integrator.order": "2 (default) | 4 | 6 | 8: the method composed to higher order",
    "integrator.composition": "[gamma_1, ..., gamma_s]: your own symmetric composition (sums to 1, palindromic)",
    "integrator.time_transform": "\"none\" (default) | \"potential\": the adaptive LGVI, its step shrinking in close "
                                 "encounters under gravity (guide: Close encounters)",
    "integrator.epsilon": "number > 0: with time_transform, the fictitious-time step, in place of step (the physical "
                          "step is epsilon g(-V) <= epsilon)",
    "integrator.monitor_scale": "number > 0: with time_transform, c in g(u) = (1 + (u/c)^4)^(-3/8) (default |V| at the "
                                "start)",
    "integrator.max_steps": "integer >= 1: with time_transform, the most steps short of duration (default 100 "
                            "duration / epsilon); reaching it fails the run, naming it",
    "integrator.exact_finish": "true or false: with time_transform, shorten the last step so that the run ends at "
                               "t = duration exactly (default false: with the first step past it)",
    # [output]
    "output.every": "integer >= 1: write every n-th step, plus the first and last (default 1)",
    "output.format": "one of the formats below (default \"csv\")",
    "output.layout": "\"single-body\" | \"long\": the trajectory's rows, one a written step with one body's "
                     "columns, or one a step and body (default: \"single-body\" for [body], \"long\" for "
                     "[[bodies]]; \"single-body\" takes one body and no short-range interaction)",
    "output.body_lists": "[[bodies]]: \"summary\" | \"file\": each body's set-up and final state in summary.json "
                         "(setup.bodies, final_bodies) or one body a line in bodies.jsonl beside it (default: the "
                         "summary up to 10 000 bodies, the file beyond)",
    # [run]
    "run.threads": "integer: threads of a many-body run (default all cores; --threads overrides)",
    "run.on_contact": "\"stop\" (default) | \"warn\" | \"ignore\": when two bodies overlap",
    # [box]
    "box.lower": "[x, y, z]: the box's lower corner",
    "box.upper": "[x, y, z]: its upper corner (each > lower)",
    "box.periodic": "[bool, bool, bool] per axis (default all true); an open axis is free space",
    # [import]
    "import.lammps_data": "string: a LAMMPS data file (atom_style full, molecular, bond or angle), relative to the scenario; each molecule one rigid body",
    "import.atom_style": "\"full\" | \"molecular\" | \"bond\" | \"angle\": where the Atoms section does not name it (\"Atoms # full\")",
    "import.radius": "number >= 0, or one per atom type (default 0: point masses): each atom a uniform ball",
    "import.periodic": "[bool, bool, bool] per axis of the file's box (default all true)",
    "import.checksum": "string, written by the run into its copy of the scenario: the data file's FNV-1a checksum; a changed file is refused",
    # [[sensor]]
    ".sensor": "array of tables [[sensor]]: what the attitude controller through the wheels reads at its samples "
              "(it needs a period); at most one of each kind",
    "sensor.kind": "\"gyro\" | \"star-tracker\"",
    "sensor.noise_density": "gyro, rad/s/sqrt(Hz), default 0: white noise on the rate (angle random walk)",
    "sensor.bias_walk": "gyro, rad/s^2/sqrt(Hz), default 0: the bias's random walk (rate random walk)",
    "sensor.initial_bias": "gyro, [x, y, z] rad/s, default 0: the bias at t = 0",
    "sensor.noise_arcsec": "star-tracker, [x, y, z] arcsec: the attitude noise's standard deviation per body axis",
    "sensor.seed": "integer >= 0, default 0: the noise's seed (an ensemble draws one per member unless "
                   "sensor_noise = \"shared\")",
    # [[forcing]]
    "forcing.kind": "\"torque\" | \"force\" | \"damping\" | \"attitude-control\" | \"wheel-torque\" (a motor torque on a [[body.wheel]]) | \"pair-damping\" (between the sites of different bodies)",
    "forcing.wheel": "wheel-torque: the wheel, by its name or its index from 0",
    "forcing.body": "string: the body it acts on (default every body); wheel-torque: the body whose wheel it turns (required with several bodies)",
    "forcing.frame": "torque: \"body\" (default) | \"inertial\"; force: \"inertial\" (default) | \"body\"",
    "forcing.value": "[a, b, c]: a constant torque or force (or table); wheel-torque: a number, N m",
    "forcing.table": "a CSV file (t, a, b, c; relative to the scenario) or rows [[t, a, b, c], ...]: interpolated linearly; must cover the run. wheel-torque: rows [[t, u], ...] from t = 0, each held until the next (zero-order hold)",
    "forcing.c": "damping: body torque -c Omega",
    "forcing.c_linear": "damping: force -c_linear v",
    "forcing.gamma": "pair-damping: > 0, the force per relative speed of two sites at zero distance, F = -gamma (1 - r/r_c)^2 (e.v) e",
    "forcing.cutoff": "pair-damping: > 0, r_c; in a periodic box below half its shortest periodic length",
    "forcing.target": "attitude-control: target quaternion (scalar first)",
    "forcing.k_p": "attitude-control: proportional gain, M = -k_p sgn(e_s) e_v - k_d Omega",
    "forcing.k_d": "attitude-control: derivative gain",
    "forcing.max_torque": "attitude-control, or torque with actuator = \"wheels\", optional: |M| scaled down to this",
    "forcing.period": "attitude-control, or torque with actuator = \"wheels\", optional: sampled at t = n period, held in between (a torque through the wheels without one: every step)",
    "forcing.actuator": "attitude-control and torque: \"torque\" (default: the torque acts on the body) | \"wheels\" (the body's [[body.wheel]] make it, u = -A^+ M; a torque in body axes)",
    "forcing.distribution": "attitude-control or torque with actuator = \"wheels\", optional: one row [dx, dy, dz] per wheel, u = D M instead of -A^+ M (-A D must be the identity)",
    # sweep files
    "sweep:.ensemble": "table: the ensemble",
    "sweep:.vary": "array of tables [[vary]]: the varied keys",
    "sweep:ensemble.scenario": "the base scenario file, relative to the sweep file",
    "sweep:ensemble.members": "with random [[vary]]: how many members; with grids only: omitted (their product)",
    "sweep:ensemble.seed": "integer: every draw comes from (seed, member index)",
    "sweep:ensemble.trajectories": "\"none\" (default) | \"all\": keep each member's run folder in DIR/members/NNNNNN",
    "sweep:ensemble.metrics": "[...] of \"pointing_error_deg\", \"settling_time\", \"max_wheel_torque\", "
                              "\"max_wheel_speed\", \"saturation_time\", \"control_effort\": GNC columns of members.csv "
                              "(pointing ones also write pointing_error.csv)",
    "sweep:ensemble.settle_band_deg": "degrees in (0, 180): the band settling_time measures to (needed by it)",
    "sweep:ensemble.sensor_noise": "\"per-member\" (default): each member's [[sensor]] seeds drawn from its index | "
                                   "\"shared\": the base's seeds in every member",
    "sweep:vary.key": "the dotted scenario key to vary, e.g. \"initial.w\"; a body by name: \"bodies.primary.omega\"; "
                      "a [[forcing]] entry by its index from 0: \"forcing.0.k_p\"; an array's element by its "
                      "indices: \"body.inertia[0][0]\"",
    "sweep:vary.normal": "{mean, std}: normal draws",
    "sweep:vary.uniform": "{low, high}: uniform draws",
    "sweep:vary.values": "[...]: a grid; several grids: their product, the last key fastest",
    "sweep:vary.rotation": "\"uniform\": attitudes uniform over SO(3)",
    "sweep:vary.attitude_error_deg": "SIGMA (degrees): attitude errors, rotations about uniformly random axes by "
                                     "normal angles of standard deviation SIGMA, composed with a quaternion key "
                                     "(or given to initial.attitude as its error)",
    "sweep:vary.normal.mean": "number or array: the mean",
    "sweep:vary.normal.std": "number or array of the same length: the standard deviation",
    "sweep:vary.uniform.low": "number or array: the lower bound",
    "sweep:vary.uniform.high": "number or array of the same length: the upper bound",
}

# Descriptions of the interaction keys (the keys themselves come from lgvi._core.INTERACTION_KEYS).
INTERACTION_DESCRIPTIONS = {
    "G": "gravitational constant (> 0)",
    "model": "\"balls\" (default) | \"inertia\": point masses of the balls, or masses and inertia tensors to second order",
    "epsilon": "energy scale epsilon (> 0)",
    "sigma": "length scale sigma (> 0)",
    "cutoff": "lennard-jones: cutoff radius r_c, > sigma (default 2.5 sigma); the energy is shifted to 0 there",
    "skin": "Verlet-list skin, >= 0 (default 0.3 sigma): lists hold pairs within r_c + skin, rebuilt after a displacement of skin/2",
    "mixing": "lennard-jones with site types: \"geometric\" (default) | \"arithmetic\": the coefficients of pairs of types not given, from each type's own",
    "pair": "lennard-jones: [[interaction.pair]] tables, each types = [i, j], epsilon, sigma: one pair of site types' coefficients",
}

ARRAYS_OF_TABLES = {"body.ball", "body.wheel", "bodies", "forcing", "vary", "sensor"}
INLINE_TABLES = {"initial.orbit", "initial.attitude", "vary.normal", "vary.uniform"}

CALL = re.compile(r"only_keys\(\s*([^,]+),\s*([^,]+),\s*(\{[^}]*\}|keys)\s*\)", re.S)


def _quoted(text):
    return re.findall(r'"([^"]*)"', text)


def _label(prefix_expr, keys, source, pos):
    """The dotted table name of one only_keys call, from its prefix expression and what precedes it."""
    p = prefix_expr.strip()
    if p.startswith('"'):
        return p.strip('"'), None
    before = source[:pos]
    if p == "ball":
        return "body.ball", None
    if p == "prefix" and "axis" in keys:
        return "body.wheel", None
    if p == "prefix" and "name" in keys:
        return "bodies", None
    if p == "prefix" and ("noise_density" in keys or "noise_arcsec" in keys):
        return "sensor", None
    if p == "prefix" and "kind" in keys:
        return "forcing", None
    if p == "p":
        return "vary", None
    raise SystemExit(f"docs_reference.py: an only_keys call with prefix {p!r} (keys {keys}) that this script does "
                     f"not know how to name; teach _label() about it")


def _variant(source, pos):
    """For a call inside `if (kind == "a" ...)` / `} else {` chains: the kinds it applies to."""
    head = source[:pos].rstrip().splitlines()
    chain = None
    for line in reversed(head[-4:]):
        if "kind ==" in line:
            return tuple(_quoted(line.split("kind ==", 1)[1].replace("kind ==", "")))
        if line.strip() == "} else {":
            chain = "else"
            break
    if chain:
        # the kinds of the enclosing r.string(..., "kind", {...}) not named by an earlier branch
        text = source[:pos]
        start = text.rfind('"kind", {')
        kinds = _quoted(text[start + len('"kind", '):text.index("}", start)])
        named = set()
        for line in text[start:].splitlines():
            if "kind ==" in line:
                named.update(_quoted(line.split("kind ==", 1)[1]))
        return tuple(k for k in kinds if k not in named)
    return None


def reader_keys(path, tag=""):
    """{table: [(key, variant)]} from the only_keys calls of one source file."""
    source = path.read_text(encoding="utf-8")
    tables = {}
    for m in CALL.finditer(source):
        if m.group(3) == "keys":
            continue  # the [interaction] table: its keys come from the registry (INTERACTION_KEYS)
        keys = _quoted(m.group(3))
        if not keys:  # only_keys(*t, q, {first, second}): the pair tables of [[vary]], named below
            continue
        table, _ = _label(m.group(2), keys, source, m.start())
        variant = _variant(source, m.start()) if "kind" in keys else None
        entry = tables.setdefault(tag + table, [])
        for k in keys:
            entry.append((k, variant))
    if tag:
        for what, first, second in re.findall(r'pair\("(\w+)", "(\w+)", "(\w+)"\)', source):
            tables.setdefault(tag + "vary." + what, []).extend([(first, None), (second, None)])
    if not tables:
        raise SystemExit(f"docs_reference.py: no only_keys calls found in {path}")
    return tables


def md_escape(text):
    return text.replace("|", "\\|")


def scenario_keys(core):
    # Any other source file that checks keys would be a reader this page does not cover.
    readers = {p.relative_to(ROOT).as_posix() for p in (ROOT / "src").rglob("*.cpp")
               if "only_keys(" in p.read_text(encoding="utf-8")}
    if readers != {"src/app/scenario.cpp", "src/app/ensemble.cpp"}:
        raise SystemExit(f"docs_reference.py: key checks in {sorted(readers)}; this script reads "
                         f"src/app/scenario.cpp and src/app/ensemble.cpp only: teach it the others")
    scen = reader_keys(ROOT / "src" / "app" / "scenario.cpp")
    sweep = reader_keys(ROOT / "src" / "app" / "ensemble.cpp", tag="sweep:")
    found = set()
    lines = ["# Scenario keys", "",
             "Every key the scenario reader accepts, generated at documentation build time from the reader's own "
             "key lists (`src/app/scenario.cpp`, `src/app/ensemble.cpp`: the lists behind its message \"unknown key; "
             "allowed here: ...\") and from the registries as the compiled module `lgvi._core` exposes them "
             "(`METHODS`, `SOLVERS`, `FORMATS`, `FORMAT_FILES`, `INTERACTION_KEYS`). What the keys mean, with "
             "examples: [Scenario files](../guide/scenario-files.md).", ""]

    def table_section(title, tables, tag):
        out = [f"## {title}", ""]
        for table in sorted(tables, key=lambda t: t != tag):  # the top level first, then the reader's order
            name = table[len(tag):]
            if name == "":
                heading = "the top level"
            elif name in ARRAYS_OF_TABLES:
                heading = f"`[[{name}]]`" + (f" and `[[bodies.{name[5:]}]]`" if name in ("body.ball", "body.wheel") else "")
            elif name in INLINE_TABLES:
                heading = f"`{name} = {{ ... }}`"
            else:
                heading = f"`[{name}]`"
            out += [f"### {heading}", "", "| key | applies to | meaning |", "|---|---|---|"]
            seen = {}
            for key, variant in tables[table]:
                seen.setdefault(key, []).append(variant)
            for key, variants in seen.items():
                dotted = f"{tag}{name}.{key}"
                found.add(dotted)
                if dotted not in DESCRIPTIONS:
                    raise SystemExit(f"docs_reference.py: the reader takes '{dotted}' and DESCRIPTIONS has no line for it")
                if None in variants:
                    applies = "all"
                else:
                    kinds = [k for v in variants for k in v]
                    applies = ", ".join(f"`{k}`" for k in dict.fromkeys(kinds))
                    applies = f"kind = {applies}"
                out.append(f"| `{key}` | {applies} | {md_escape(DESCRIPTIONS[dotted])} |")
            out.append("")
        return out

    # The reader checks [[bodies.ball]] and [[bodies.wheel]] with the same code as [[body.ball]] and [[body.wheel]].
    lines += table_section("Scenario files (`lgvi run`, `lgvi compare`)", scen, "")
    lines += ["### `[interaction]`", "",
              "`kind` is one of " + ", ".join(f'`"{k}"`' for k in core.INTERACTIONS) + " (default `\"none\"`); "
              "each kind takes `kind` and its own keys:", "",
              "| kind | keys |", "|---|---|"]
    for kind in core.INTERACTIONS:
        keys = core.INTERACTION_KEYS[kind]
        lines.append(f"| `{kind}` | " + (", ".join(f"`{k}`" for k in keys) or "(none)") + " |")
    lines += ["", "| key | meaning |", "|---|---|"]
    all_interaction_keys = sorted({k for ks in core.INTERACTION_KEYS.values() for k in ks})
    for k in all_interaction_keys:
        if k not in INTERACTION_DESCRIPTIONS:
            raise SystemExit(f"docs_reference.py: interaction key '{k}' has no line in INTERACTION_DESCRIPTIONS")
        lines.append(f"| `{k}` | {md_escape(INTERACTION_DESCRIPTIONS[k])} |")
    stale = set(INTERACTION_DESCRIPTIONS) - set(all_interaction_keys)
    lines += [""]
    lines += ["### Names", "",
              "| key | values (in the registry's order; the first is the default) |", "|---|---|",
              "| `integrator.method` | " + ", ".join(f'`"{m}"`' for m in core.METHODS) + " |",
              "| `integrator.solver` | " + ", ".join(f'`"{s}"`' for s in core.SOLVERS) + " |",
              "| `output.format` | " + ", ".join(f'`"{f}"` ({core.FORMAT_FILES[f][0]})' for f in core.FORMATS) + " |",
              "| `interaction.kind` | " + ", ".join(f'`"{k}"`' for k in core.INTERACTIONS) + " |", ""]
    lines += table_section("Sweep files (`lgvi ensemble`)", sweep, "sweep:")
    stale |= {k for k in DESCRIPTIONS if k not in found and not k.startswith("bodies.ball")}
    if stale:
        raise SystemExit(f"docs_reference.py: described but not taken by the reader: {sorted(stale)}")
    return "\n".join(lines) + "\n"


def _lgvi(binary, *args):
    """Output of the built binary, run as `lgvi` (its help names argv[0])."""
    return subprocess.run(["lgvi", *args], executable=binary, capture_output=True, text=True, check=True).stdout


def commands(binary):
    top = _lgvi(binary, "--help")
    names = []
    section = top.split("Subcommands:", 1)[1].strip("\n").split("\n\n", 1)[0]
    for line in section.splitlines():
        m = re.match(r"\s{2}(\w[\w-]*)\s", line)
        if m:
            names.append(m.group(1))
    if not names:
        raise SystemExit("docs_reference.py: no subcommands found in `lgvi --help`")
    out = ["# Commands and options", "",
           "The help of the built `lgvi` binary, captured when this page was built. How the commands are used: "
           "[The command line](../guide/command-line.md).", "", "## `lgvi`", "", "```text", top.rstrip(), "```", ""]
    for name in names:
        out += [f"## `lgvi {name}`", "", "```text", _lgvi(binary, name, "--help").rstrip(), "```", ""]
    out += ["`lgvi --version`: `" + _lgvi(binary, "--version").strip() + "`", ""]
    return "\n".join(out) + "\n"


def _json_keys(obj, prefix=""):
    """Dotted key paths of a JSON object (lists: their first element, as NAME[])."""
    keys = []
    if isinstance(obj, dict):
        for k, v in obj.items():
            path = f"{prefix}.{k}" if prefix else k
            keys.append(path)
            keys += _json_keys(v, path)
    elif isinstance(obj, list) and obj and isinstance(obj[0], dict):
        keys += _json_keys(obj[0], prefix + "[]")
    return keys


def outputs(core, binary):
    out = ["# Output columns and summary keys", "",
           "Generated at documentation build time: the trajectory columns from the compiled module "
           "(`lgvi._core`, the headers the writers use), the summary keys from `summary.json` files of real runs "
           "of the built binary. What they mean: [Reading the outputs](../getting-started.md#reading-the-outputs), "
           "[Forcing](../guide/forcing.md), [Many bodies](../guide/many-bodies.md), "
           "[Orbit and attitude](../guide/orbit-attitude.md).", "", "## Trajectory columns", "",
           "| trajectory | columns |", "|---|---|"]
    for what, attr in [("one body", "TRAJECTORY_HEADER"), ("one body, forced", "FORCED_TRAJECTORY_HEADER"),
                       ("`[[bodies]]` (long format: one row per step and body)", "BODIES_TRAJECTORY_HEADER"),
                       ("`[[bodies]]`, forced", "FORCED_BODIES_TRAJECTORY_HEADER")]:
        header = getattr(core, attr)
        cols = header.split(",")
        out.append(f"| {what} ({len(cols)}) | " + ", ".join(f"`{c}`" for c in cols) + " |")
    out += ["", "A molecular run (`[[bodies]]` with a short-range pair interaction: `lennard-jones`, `wca`) adds "
            + " and ".join(f"`{c}`" for c in core.THERMO_COLUMNS)
            + " after those (the pressure in a box periodic along every axis only): the kinetic temperature "
            "2 K / (6 N - 3) with k_B = 1 and the pressure of the rigid molecules (2 K_trans + W) / 3V "
            "([Many bodies](../guide/many-bodies.md#temperature-and-pressure))."]
    out += ["", "## Output files by format", "", "| `[output] format` | file in the run folder | holds the trajectory's columns |",
            "|---|---|---|"]
    for f in core.FORMATS:
        name, columns = core.FORMAT_FILES[f]
        out.append(f"| `{f}` | `{name}` | {'yes' if columns else 'no: an export for viewers'} |")
    out.append("")
    runs = {
        "a single body (`scenarios/paper-orbit.toml`)": ("run", ROOT / "scenarios" / "paper-orbit.toml"),
        "a forced single body (`scenarios/attitude-slew.toml`)": ("run", ROOT / "scenarios" / "attitude-slew.toml"),
        "many bodies (`scenarios/binary-asteroid.toml`)": ("run", ROOT / "scenarios" / "binary-asteroid.toml"),
        "an adaptive step (`scenarios/paper-close-pass.toml`)": ("run", ROOT / "scenarios" / "paper-close-pass.toml"),
        "a periodic molecular gas (`tests/cli/good/periodic-gas.toml`)":
            ("run", ROOT / "tests" / "cli" / "good" / "periodic-gas.toml"),
        "the same with its lists of bodies in a file (`[output] body_lists = \"file\"`, the default beyond 10 000 "
        "bodies)": ("run", ROOT / "tests" / "cli" / "good" / "periodic-gas.toml"),
        "a body with reaction wheels (`scenarios/slew-wheels.toml`)": ("run", ROOT / "scenarios" / "slew-wheels.toml"),
    }
    out += ["## `summary.json` keys", "",
            "Dotted paths; `NAME[]` is an array of objects (its elements' keys listed once). Runs are shortened "
            "to a few steps for this page; the keys do not depend on the length.", ""]
    with tempfile.TemporaryDirectory() as tmp:
        tmp = pathlib.Path(tmp)
        for i, (what, (cmd, scenario)) in enumerate(runs.items()):
            text = scenario.read_text(encoding="utf-8")
            text = re.sub(r"(?m)^duration\s*=.*$", "duration = 0.0", text)
            if "body_lists" in what:  # (this scenario has an [output] table)
                text = text.replace("[output]\n", '[output]\nbody_lists = "file"\n', 1)
            short = tmp / f"s{i}_{scenario.name}"
            short.write_text(text)
            # a table of forcing given as a file is resolved relative to the scenario: keep them beside it
            for extra in scenario.parent.glob("*.csv"):
                (tmp / extra.name).write_bytes(extra.read_bytes())
            folder = tmp / f"run{i}"
            _lgvi(binary, "run", str(short), "--out", str(folder), "--no-figures", "-q")
            summary = json.loads((folder / "summary.json").read_text())
            keys = _json_keys(summary)
            out += [f"### {what}", "", ", ".join(f"`{k}`" for k in keys), ""]
            if (folder / "bodies.jsonl").exists():
                line = json.loads((folder / "bodies.jsonl").read_text().splitlines()[0])
                out += ["The keys of a line of `bodies.jsonl` (one body a line, in scenario order): "
                        + ", ".join(f"`{k}`" for k in _json_keys(line)) + ".", ""]
            if i == 0:
                run_files = sorted(p.name for p in folder.iterdir())
        # An ensemble of two members of the shortened paper orbit, random attitudes.
        sweep = tmp / "sweep.toml"
        sweep.write_text('[ensemble]\nscenario = "s0_paper-orbit.toml"\nmembers = 2\nseed = 1\n\n'
                         '[[vary]]\nkey = "initial.quaternion"\nrotation = "uniform"\n', encoding="utf-8")
        folder = tmp / "ensemble"
        _lgvi(binary, "ensemble", str(sweep), "--out", str(folder), "-q", "--no-figures")
        header = (folder / "members.csv").read_text(encoding="utf-8").splitlines()[0].split(",")
        files = sorted(p.name for p in folder.iterdir())
        # A comparison of one method on the free body, as short as the options allow.
        folder = tmp / "compare"
        _lgvi(binary, "compare", str(ROOT / "scenarios" / "free-body-manchester-peck.toml"), "--methods", "lgvi",
              "--ladder", "2", "--long-steps", "1000", "--timing-budget", "0.01", "--error-time", "1",
              "--no-figures", "-q", "--out", str(folder))
        compare_files = sorted(p.name for p in folder.iterdir())
        compare_columns = {f: (folder / f).read_text(encoding="utf-8").splitlines()[0].split(",")
                           for f in compare_files if f.endswith(".csv")}
    out += ["## Run folders (`lgvi run`)", "",
            "The files of a run folder (`--no-figures`; with figures also `trajectory.png`, `body_motion.png`, "
            "`energy_error.png`, `quaternion_error.png`, `momentum_error.png`; with `--checkpoint-every`, "
            "`checkpoint.bin`): " + ", ".join(f"`{f}`" for f in run_files) + ".", ""]
    out += ["## Comparisons (`lgvi compare`)", "",
            "The files of a comparison of a single body (`--no-figures`; a system adds `reference.json`): "
            + ", ".join(f"`{f}`" for f in compare_files) + ".", ""]
    for f, columns in compare_columns.items():
        out += [f"`{f}`: " + ", ".join(f"`{c}`" for c in columns) + ".", ""]
    out += ["## Ensembles (`lgvi ensemble`)", "",
            "`members.csv` of an ensemble of the paper orbit varying `initial.quaternion` (the varied keys' "
            "columns follow `index`; a `[[bodies]]` base scenario has `NAME.x ...` per body for the final state): "
            + ", ".join(f"`{c}`" for c in header) + ".", "",
            "The files of an ensemble folder (`--no-figures`): " + ", ".join(f"`{f}`" for f in files) + ".", "",
            "With `[ensemble] metrics` their columns follow `max_linear_momentum_error`, in the order given, and a "
            "pointing metric adds `pointing_error.csv` (`index`, `t`, `pointing_error_deg`: each member's pointing "
            "error at the base's output frames) ([Ensembles](../guide/ensembles.md#monte-carlo-for-guidance-"
            "navigation-and-control)).", ""]
    return "\n".join(out) + "\n"


HEADER_ORDER = ["s3.hpp", "rigid_body.hpp", "potential.hpp", "state.hpp", "rotation_solver.hpp", "system.hpp",
                "stepper.hpp", "interaction.hpp", "lgvi.hpp", "integrate.hpp", "composition.hpp", "forcing.hpp"]


def cpp_api(xml_dir):
    """The C++ API page: a table of what each public header declares (from doxygen's XML, linked into the
    namespace's entries below it), then the namespace lgvi through breathe."""
    import xml.etree.ElementTree as ET
    headers = {}
    for f in sorted(xml_dir.glob("*_8hpp.xml")):
        compound = ET.parse(f).getroot().find("compounddef")
        path = compound.find("location").get("file")
        brief = " ".join("".join(compound.find("briefdescription").itertext()).split())
        classes = [c.text for c in compound.findall("innerclass") if c.text.count("::") == 1]
        headers[path] = {"brief": brief, "names": list(classes)}
    concepts = []
    for f in sorted(xml_dir.glob("concept*.xml")):
        compound = ET.parse(f).getroot().find("compounddef")
        concepts.append(compound.find("compoundname").text)
        headers.setdefault(compound.find("location").get("file"), {"brief": "", "names": []})["names"].append(
            compound.find("compoundname").text)
    for f in sorted(xml_dir.glob("namespacelgvi*.xml")):
        compound = ET.parse(f).getroot().find("compounddef")
        ns = compound.find("compoundname").text
        for m in compound.iter("memberdef"):
            name = f"{ns}::{m.find('name').text}"
            entry = headers.setdefault(m.find("location").get("file"), {"brief": "", "names": []})
            if name not in entry["names"]:
                entry["names"].append(name)
    if not headers:
        raise SystemExit(f"docs_reference.py: no doxygen XML of headers in {xml_dir}")

    def order(path):
        base = path.split("lgvi/", 1)[-1]
        return (HEADER_ORDER.index(base) if base in HEADER_ORDER else len(HEADER_ORDER), base)

    out = ["# C++ API", "",
           "The public headers in `include/lgvi/`, documented from their comments by doxygen (XML) and breathe. "
           "How to use the library: [The C++ library](../guide/library.md). The table lists what each header "
           "declares (generated from doxygen's XML), linked to its entry in the namespace `lgvi` below.", "",
           "| header | declares |", "|---|---|"]
    for path in sorted(headers, key=order):
        names = list(dict.fromkeys(re.sub(r"<.*>$", "", n).strip() for n in headers[path]["names"]))
        shown = "lgvi/" + path.split("lgvi/", 1)[-1]
        out.append(f"| `{shown}` | " + (", ".join("{cpp:any}`" + n + "`" for n in names) or "—") + " |")
    out += ["", "## Concepts", "", "```{eval-rst}"] + [f".. doxygenconcept:: {c}" for c in concepts] + ["```", ""]
    out += ["## namespace lgvi", "", "```{eval-rst}", ".. doxygennamespace:: lgvi", "   :members:",
            "   :undoc-members:", "```", ""]
    return "\n".join(out) + "\n"


def main():
    build, dest = pathlib.Path(sys.argv[1]).resolve(), pathlib.Path(sys.argv[2])
    sys.path.insert(0, str(build / "python"))
    import lgvi._core as core
    binary = str(build / "lgvi")
    dest.mkdir(parents=True, exist_ok=True)
    (dest / "scenario-keys.md").write_text(scenario_keys(core), encoding="utf-8")
    (dest / "commands.md").write_text(commands(binary), encoding="utf-8")
    (dest / "outputs.md").write_text(outputs(core, binary), encoding="utf-8")
    (dest / "cpp.md").write_text(cpp_api(build / "docs" / "doxygen" / "xml"), encoding="utf-8")


if __name__ == "__main__":
    main()
