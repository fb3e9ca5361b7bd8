"""TOML text for the compiled scenario reader: how the package spells values and scenario
documents, so that scenarios built in code get exactly the file reader's validation and
messages. Imports nothing of lgvi (the layer above _columns, _check and _attitude; _api and
_ensemble write their TOML with it)."""

import json
import math


def toml_value(v):
    """A Python value (bool, int, float, str, list/tuple, dict) as TOML text."""
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, int):
        return str(v)
    if isinstance(v, float):
        if not math.isfinite(v):  # checked before; TOML's own spelling keeps the reader's message
            return "nan" if math.isnan(v) else ("inf" if v > 0 else "-inf")
        return repr(v)  # shortest text that round-trips exactly
    if isinstance(v, str):
        return json.dumps(v)  # a TOML basic string (JSON escapes are TOML escapes)
    if isinstance(v, (list, tuple)):
        return "[" + ", ".join(toml_value(x) for x in v) + "]"
    if isinstance(v, dict):  # an inline table ([initial] orbit, attitude)
        return "{ " + ", ".join(f"{k} = {toml_value(x)}" for k, x in v.items()) + " }"
    raise TypeError(f"cannot write {v!r} as TOML")


def scenario_text(doc):
    """TOML text of a scenario document (tables of scalars/arrays; body.ball an array of tables)."""
    lines = []
    for table in ("body", "potential", "initial", "integrator", "output"):
        if table not in doc:
            continue
        t = doc[table]
        lines.append(f"[{table}]")
        for k, v in t.items():
            if table == "body" and k == "ball":
                continue
            lines.append(f"{k} = {toml_value(v)}")
        for ball in t.get("ball", []) if table == "body" else []:
            lines.append("[[body.ball]]")
            lines.extend(f"{k} = {toml_value(v)}" for k, v in ball.items())
        lines.append("")
    return "\n".join(lines)
