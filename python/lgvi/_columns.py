"""The trajectory columns and the summary's body: the leaf of the package's
pure-Python modules (data -> io -> plot import it; it imports nothing of lgvi)."""

#: The trajectory's columns, in the order of the CLI's trajectory.csv header.
COLUMNS = ("t", "x", "y", "z", "qw", "qx", "qy", "qz", "px", "py", "pz", "wx", "wy", "wz", "energy", "energy_error",
           "quat_norm_error", "Lx", "Ly", "Lz", "momentum_error")
HEADER = ",".join(COLUMNS)

#: The columns of a many-body ([[bodies]]) trajectory, the long format: per
#: written step and body the body's index and state and its |q| - 1, then
#: the system's energy, energy error, total linear momentum P and its error
#: |P - P0| / sum |p_a0|, total angular momentum L and its error |L - L0|.
BODIES_COLUMNS = ("t", "body", "x", "y", "z", "qw", "qx", "qy", "qz", "px", "py", "pz", "wx", "wy", "wz",
                  "quat_norm_error", "energy", "energy_error", "Px", "Py", "Pz", "linear_momentum_error",
                  "Lx", "Ly", "Lz", "momentum_error")

#: The column a forced scenario ([[forcing]]) adds after the others: the work
#: W done by the forcing since t = 0 (its energy_error is then E - E0 - W).
WORK = "work"
FORCED_COLUMNS = COLUMNS + (WORK,)
FORCED_BODIES_COLUMNS = BODIES_COLUMNS + (WORK,)

#: The columns a molecular run (a many-body scenario with a short-range pair
#: interaction) adds after those (and after "work" when forced): the kinetic
#: temperature 2 K / (6 N - 3), and in a box periodic along every axis the
#: pressure of the rigid molecules (2 K_trans + W) / 3V (the summary's
#: "thermodynamics" says which, and the convention).
THERMO_COLUMNS = ("temperature", "pressure")


#: The columns a body with reaction wheels adds at the end, per wheel NAME (the summary's setup.body.wheels,
#: in order): its speed relative to the body, its axial momentum and the torque applied over the step from
#: the row's time.
WHEEL_QUANTITIES = ("speed", "momentum", "torque")


def wheel_columns(summary):
    """The wheel columns of a single-body layout's body with reaction wheels ("NAME.speed", ...), () without."""
    wheels = body_of(summary).get("wheels") or []
    return tuple(f"{w['name']}.{q}" for w in wheels for q in WHEEL_QUANTITIES)


def single_columns(names):
    """The single-body layout's column names as a tuple if ``names`` are one of its layouts (COLUMNS, then
    "work" when forced, then any reaction wheels' NAME.speed, NAME.momentum, NAME.torque), else None."""
    names = tuple(names)
    if names[:len(COLUMNS)] != COLUMNS:
        return None
    tail = names[len(COLUMNS):]
    if tail[:1] == (WORK,):
        tail = tail[1:]
    if len(tail) % 3 or any(not n.endswith("." + WHEEL_QUANTITIES[i % 3]) for i, n in enumerate(tail)):
        return None
    return names


def bodies_columns(names):
    """The long format's column names as a tuple if ``names`` are one of its layouts (BODIES_COLUMNS, then "work"
    when forced, then "temperature" and "pressure" or "temperature" alone), else None."""
    names = tuple(names)
    if names[:len(BODIES_COLUMNS)] != BODIES_COLUMNS:
        return None
    tail = names[len(BODIES_COLUMNS):]
    if tail[:1] == (WORK,):
        tail = tail[1:]
    return names if tail in ((), THERMO_COLUMNS[:1], THERMO_COLUMNS) else None


def bodies_columns_of(width, summary):
    """The long format's column names of rows ``width`` wide, from the run's summary: "work" when it has the
    forcing's work, then the columns its "thermodynamics" names."""
    names = BODIES_COLUMNS + ((WORK,) if "work" in summary else ())
    thermo = summary.get("thermodynamics") or {}
    names += tuple(c for c in THERMO_COLUMNS if c in thermo)
    if len(names) != width:
        raise ValueError(f"data: {width} columns, but the summary says {len(names)} ({','.join(names)})")
    return names


def body_of(summary):
    """The body of a one-body run's summary: setup.body (a [body] scenario's, the CLI's layout) or body, or the
    one entry of setup.bodies (a [[bodies]] scenario of one body); {} if none."""
    if not isinstance(summary, dict):
        return {}
    setup = summary.get("setup") or {}
    body = summary.get("body")
    if body is None:
        body = setup.get("body")
    if body is None and len(setup.get("bodies") or []) == 1:
        body = setup["bodies"][0]
    return body or {}
