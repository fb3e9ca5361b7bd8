"""lgvi: rigid bodies on unit quaternions, the structure-preserving way (Shen & Leok's Lie group
variational integrator), from Python.

    import lgvi
    scenario = lgvi.Scenario.from_toml("scenarios/paper-orbit.toml")
    result = lgvi.simulate(scenario)          # numpy arrays + summary dict
    result.q                                  # (N, 4) unit quaternions, scalar-first (w, x, y, z)
    lgvi.plot.draw_figures(result, "figures")

Public names: Body, Scenario, simulate, Result (a run of one body or many), BodyTrajectory, Stepper,
PythonPotential, PythonForcing (forces and torques written in Python), IntegrationError, ensemble,
EnsembleResult (sweeps and Monte Carlo on any executor), load, potential (none(), central(mu),
uniform(g)), plot (the paper's figures), view (an interactive 3-D view of a run, one offline HTML
file), load_run, load_bodies (a many-body run's bodies: set-up and final state), COLUMNS,
BODIES_COLUMNS, METHODS, SOLVERS, FORMATS, INTERACTIONS (the names the scenario reader accepts); SystemResult
(deprecated: Result holds many-body runs too).
Quaternions are scalar-first (w, x, y, z) numpy arrays everywhere. Invalid arguments raise ValueError
naming the argument.

`import lgvi` itself is cheap: names are loaded on first use (numpy, and the compiled lgvi._core
for Body, Scenario, simulate, Stepper), so `python3 -m lgvi.plot` also works from the source tree
(python/), which has no compiled module.
"""

# name -> submodule that defines it
_EXPORTS = {
    "Body": "_api", "Scenario": "_api", "simulate": "_api", "Stepper": "_api", "IntegrationError": "_api",
    "METHODS": "_api", "SOLVERS": "_api", "FORMATS": "_api", "INTERACTIONS": "_api",
    "__version__": "_api",
    "PythonPotential": "potential",
    "PythonForcing": "forcing",
    "Result": "_result", "BodyTrajectory": "_result", "COLUMNS": "_result", "SystemResult": "_result",
    "BODIES_COLUMNS": "_result",
    "load": "_io",
    "load_run": "_io",
    "load_bodies": "_io",
    "ensemble": "_ensemble", "EnsembleResult": "_ensemble",
    "view": "viewer",
}
_SUBMODULES = ("plot", "potential", "forcing")

__all__ = ["Body", "Scenario", "simulate", "Result", "BodyTrajectory", "SystemResult", "Stepper", "PythonPotential",
           "PythonForcing", "IntegrationError",
           "load", "potential", "plot", "load_run", "load_bodies", "COLUMNS", "BODIES_COLUMNS", "METHODS", "SOLVERS",
           "FORMATS", "INTERACTIONS",
           "ensemble", "EnsembleResult", "view"]


def _import(submodule):
    import importlib  # here, not at module level: dir(lgvi) lists only the public names
    try:
        return importlib.import_module("." + submodule, __name__)
    except ImportError as e:
        if submodule != "_api" or "_core" not in f"{e.name} {e}":
            raise
        import os
        here = os.path.dirname(os.path.abspath(__file__))
        raise ImportError(
            f"lgvi: the compiled module lgvi._core is not in {here} (this is the source tree's copy of the "
            f"package). Build lgvi (scripts/setup.sh, or cmake) and use the package in build/python: "
            f"scripts/setup.sh registers it with /usr/bin/python3 (lgvi.pth), or set "
            f"PYTHONPATH=<build>/python.", name="lgvi._core") from e


def __getattr__(name):
    # Lazy, so that `import lgvi` (and `python3 -m lgvi.plot`) imports neither numpy nor the compiled module.
    if name in _SUBMODULES:
        return _import(name)
    if name in _EXPORTS:
        value = getattr(_import(_EXPORTS[name]), name)
        globals()[name] = value
        return value
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def __dir__():
    return sorted(set(globals()) | set(__all__) | {"__version__"})
