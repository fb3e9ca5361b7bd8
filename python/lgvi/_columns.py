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


def body_of(summary):
    """The body of a summary: setup.body (the CLI's layout) or body."""
    if not isinstance(summary, dict):
        return {}
    body = summary.get("body")
    if body is None:
        body = (summary.get("setup") or {}).get("body")
    return body or {}
