"""Argument checks of the public API: every problem is a ValueError whose
message starts with the argument's name ("quaternion: ...")."""

import math
import numbers

import numpy as np



def _describe(value):
    text = repr(value)
    return text if len(text) <= 80 else text[:77] + "..."


def boolean(value, name):
    """`value` as a bool: True or False (numpy's too), nothing else."""
    if not isinstance(value, (bool, np.bool_)):
        raise ValueError(f"{name}: must be True or False, got {_describe(value)}")
    return bool(value)


def array(value, name, shape):
    """`value` as a float64 array of exactly `shape`, all finite."""
    want = "(" + ", ".join(str(n) for n in shape) + ("," if len(shape) == 1 else "") + ")"
    if value is None or isinstance(value, (str, bytes, dict)):
        raise ValueError(f"{name}: must be numbers of shape {want}, got {_describe(value)}")
    try:
        a = np.array(value, dtype=float)
    except (TypeError, ValueError):
        raise ValueError(f"{name}: must be numbers of shape {want}, got {_describe(value)}") from None
    if a.shape != tuple(shape):
        raise ValueError(f"{name}: must have shape {want}, got shape {a.shape}")
    if not np.all(np.isfinite(a)):
        raise ValueError(f"{name}: must be finite, got {_describe(a.tolist())}")
    return a


def vector3(value, name):
    """A finite 3-vector, shape (3,)."""
    return array(value, name, (3,))


def matrix3(value, name):
    """A finite 3x3 matrix."""
    return array(value, name, (3, 3))


def quaternion(value, name):
    """A scalar-first (w, x, y, z) quaternion within 1e-6 of unit norm (returned as given).

    The check is the library's (S3::from_quaternion_checked, through lgvi._core), the
    same as for scenario files.
    """
    q = array(value, name, (4,))
    from . import _core
    _core.check_quaternion(q, name)
    return q


def number(value, name):
    """A finite real number (not a bool)."""
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, numbers.Real):
        raise ValueError(f"{name}: must be a number, got {_describe(value)}")
    x = float(value)
    if not math.isfinite(x):
        raise ValueError(f"{name}: must be finite, got {x!r}")
    return x


def positive(value, name):
    x = number(value, name)
    if not x > 0.0:
        raise ValueError(f"{name}: must be > 0, got {x!r}")
    return x


def non_negative(value, name):
    x = number(value, name)
    if not x >= 0.0:
        raise ValueError(f"{name}: must be >= 0, got {x!r}")
    return x


def integer(value, name, low=None, high=None):
    """An int (or numpy integer) in [low, high]."""
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, numbers.Integral):
        raise ValueError(f"{name}: must be an integer, got {_describe(value)}")
    n = int(value)
    if (low is not None and n < low) or (high is not None and n > high):
        bounds = f"[{low}, {high}]" if high is not None else f">= {low}"
        raise ValueError(f"{name}: must be an integer {'in ' if high is not None else ''}{bounds}, got {n}")
    return n


def choice(value, name, allowed):
    if not isinstance(value, str) or value not in allowed:
        listed = ", ".join(f'"{a}"' for a in allowed)
        raise ValueError(f"{name}: must be one of {listed}, got {_describe(value)}")
    return value
