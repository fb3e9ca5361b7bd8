"""lgvi: Python side of the lgvi rigid-body integrator; plotting and trajectory loading.

Quaternions are scalar-first (qw, qx, qy, qz) everywhere.
"""

__all__ = ["plot", "load_run"]


def __getattr__(name):
    # Lazy access so that `import lgvi` stays cheap (no numpy/matplotlib).
    if name in __all__:
        import importlib
        module = importlib.import_module(".plot", __name__)
        return module if name == "plot" else module.load_run
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
