"""Type stubs of the public API of `lgvi` (the runtime loads these names lazily).

Quaternions are scalar-first (w, x, y, z) numpy arrays everywhere.
"""

import os
from typing import Any, Callable, Dict, List, Literal, Mapping, Optional, Sequence, Tuple, Union

import numpy as np
import numpy.typing as npt

from . import plot as plot
from . import forcing as forcing
from . import potential as potential
from .forcing import PythonForcing as PythonForcing
from .potential import PythonPotential as PythonPotential

__version__: str

COLUMNS: Tuple[str, ...]
BODIES_COLUMNS: Tuple[str, ...]
METHODS: Tuple[str, ...]
SOLVERS: Tuple[str, ...]
FORMATS: Tuple[str, ...]
INTERACTIONS: Tuple[str, ...]

Layout = Literal["single-body", "long"]  # [output] layout: the trajectory's rows

# The names of the C++ tables (lgvi._core.METHODS, SOLVERS, FORMATS, INTERACTIONS), in their
# order; tests/python/test_name_lists.py fails when these disagree with them.
Method = Literal["lgvi", "lgvi-lagrangian", "so3-lgvi", "rattle-quaternion", "rk4-normalized", "euler-exp",
                 "no-squish", "splitting-dlm", "exact"]
Solver = Literal["newton", "newton-exp", "broyden"]
OutputFormat = Literal["csv", "npz", "hdf5", "xyz", "vtk", "lammps-dump"]
#: [interaction] kind, the value of interaction={"kind": ...}.
InteractionKind = Literal["none", "gravity", "lennard-jones", "wca"]
Vector3 = Union[Sequence[float], npt.NDArray[np.float64]]
#: A unit quaternion, scalar-first (w, x, y, z).
Quaternion = Union[Sequence[float], npt.NDArray[np.float64]]
Matrix3 = Union[Sequence[Sequence[float]], npt.NDArray[np.float64]]
BallSpec = Union[Tuple[Vector3, float], Tuple[Vector3, float, float], Mapping[str, Any]]
PotentialSpec = Union[None, Literal["none"], Mapping[str, Any]]
#: (x (3,), q (4,) scalar-first (w, x, y, z)) -> (energy, force (3,), body torque (3,))
PotentialFunction = Callable[[npt.NDArray[np.float64], npt.NDArray[np.float64]],
                             Tuple[float, Vector3, Vector3]]
PathLike = Union[str, os.PathLike[str]]

class IntegrationError(RuntimeError):
    """A failed step; `result` is the Result up to the last good step (None from Stepper.step)."""
    step: int
    time: float
    result: Optional[Result]

class Body:
    """A rigid body: mass, standard inertia J (about the centre of mass, body axes), optional balls."""
    def __init__(self, mass: Optional[float] = ..., inertia: Optional[Matrix3] = ...,
                 balls: Optional[Sequence[BallSpec]] = ..., radius: Optional[float] = ...) -> None: ...
    @classmethod
    def from_balls(cls, balls: Sequence[BallSpec]) -> Body:
        """A body of uniform balls (position, mass, radius); centre of mass moved to the origin."""
        ...
    @classmethod
    def sphere(cls, radius: float, density: Optional[float] = ..., mass: Optional[float] = ...) -> Body:
        """A uniform solid sphere (exactly one of density, mass): J = 2/5 m r^2 I."""
        ...
    @classmethod
    def ellipsoid(cls, semi_axes: Vector3, density: Optional[float] = ..., mass: Optional[float] = ...) -> Body:
        """A uniform solid ellipsoid, semi-axes along the body axes (exactly one of density, mass)."""
        ...
    @property
    def extent(self) -> Literal["balls", "sphere", "ellipsoid", "point"]: ...
    @property
    def semi_axes(self) -> npt.NDArray[np.float64]: ...
    @property
    def mass(self) -> float: ...
    @property
    def inertia(self) -> npt.NDArray[np.float64]:
        """J, 3x3."""
        ...
    @property
    def inertia_inverse(self) -> npt.NDArray[np.float64]: ...
    @property
    def rotational_dof(self) -> int:
        """3; 2 for a linear body (point masses on one line); 0 for a point mass."""
        ...
    @property
    def linear_axis(self) -> npt.NDArray[np.float64]: ...
    @property
    def balls(self) -> List[Dict[str, Any]]:
        """[{"position": (3,) relative to the centre of mass, "mass": m, "radius": r}, ...]."""
        ...

class Scenario:
    """One run: body, potential, initial state (quaternion scalar-first (w, x, y, z)), integrator, output."""
    def __init__(self, *, body: Body, step: Optional[float] = ..., duration: float, potential: PotentialSpec = ...,
                 position: Optional[Vector3] = ..., quaternion: Optional[Quaternion] = ...,
                 momentum: Optional[Vector3] = ...,
                 velocity: Optional[Vector3] = ..., w: Optional[Vector3] = ..., omega: Optional[Vector3] = ...,
                 method: Method = ..., solver: Solver = ..., tolerance: Optional[float] = ...,
                 max_iterations: Optional[int] = ..., predictor_order: Optional[int] = ...,
                 order: Optional[int] = ..., composition: Optional[Sequence[float]] = ..., every: int = ...,
                 output_format: OutputFormat = ..., name: str = ...,
                 orbit: Optional[Mapping[str, float]] = ...,
                 attitude: Optional[Mapping[str, Union[str, float]]] = ...,
                 time_transform: Optional[Literal["none", "potential"]] = ..., epsilon: Optional[float] = ...,
                 monitor_scale: Optional[float] = ..., max_steps: Optional[int] = ...,
                 exact_finish: Optional[bool] = ...) -> None: ...
    @classmethod
    def from_toml(cls, path: PathLike) -> Scenario:
        """Read a scenario file exactly as `lgvi run` does."""
        ...
    @classmethod
    def from_string(cls, text: str, name: str = ...,
                    directory: Optional[Union[str, "os.PathLike[str]"]] = ...) -> Scenario:
        """Parse scenario TOML text exactly as `lgvi run` does; relative paths in it from `directory`."""
        ...
    @classmethod
    def from_arrays(cls, *, bodies: Union[Body, Sequence[Body]], positions: npt.ArrayLike, quaternions: npt.ArrayLike,
                    step: Optional[float] = ..., duration: float, momenta: Optional[npt.ArrayLike] = ...,
                    velocities: Optional[npt.ArrayLike] = ..., w: Optional[npt.ArrayLike] = ...,
                    omegas: Optional[npt.ArrayLike] = ..., names: Optional[Sequence[str]] = ...,
                    potential: PotentialSpec = ..., interaction: Optional[Dict[str, Any]] = ...,
                    method: Method = ..., order: Optional[int] = ..., every: int = ..., threads: Optional[int] = ...,
                    on_contact: Optional[Literal["stop", "warn", "ignore"]] = ...,
                    box: Optional[Dict[str, Any]] = ..., name: str = ...,
                    time_transform: Optional[Literal["none", "potential"]] = ..., epsilon: Optional[float] = ...,
                    monitor_scale: Optional[float] = ..., max_steps: Optional[int] = ...,
                    exact_finish: Optional[bool] = ...) -> Scenario:
        """A scenario of N bodies from (N, 3) / (N, 4) arrays, validated by the reader of `lgvi run`."""
        ...
    @classmethod
    def from_lammps_data(cls, path: Union[str, "os.PathLike[str]"], *, interaction: Dict[str, Any], step: float,
                         duration: float, radius: Union[None, float, Sequence[float]] = ...,
                         periodic: Optional[Sequence[bool]] = ...,
                         atom_style: Optional[Literal["full", "molecular", "bond", "angle"]] = ...,
                         potential: PotentialSpec = ...,
                         method: Method = ..., order: Optional[int] = ..., every: int = ...,
                         threads: Optional[int] = ..., on_contact: Optional[Literal["stop", "warn", "ignore"]] = ...,
                         name: Optional[str] = ...) -> Scenario:
        """The molecules of a LAMMPS data file as rigid bodies ([import] lammps_data)."""
        ...
    def replace(self, *, body: Body = ..., potential: PotentialSpec = ..., position: Vector3 = ...,
                quaternion: Quaternion = ..., momentum: Vector3 = ..., velocity: Vector3 = ..., w: Vector3 = ...,
                omega: Vector3 = ..., method: Method = ..., solver: Solver = ..., step: float = ...,
                duration: float = ..., tolerance: Optional[float] = ..., max_iterations: Optional[int] = ...,
                predictor_order: Optional[int] = ..., order: Optional[int] = ...,
                composition: Optional[Sequence[float]] = ..., every: int = ..., output_format: OutputFormat = ...,
                name: str = ..., time_transform: Optional[Literal["none", "potential"]] = ...,
                epsilon: Optional[float] = ..., monitor_scale: Optional[float] = ...,
                max_steps: Optional[int] = ..., exact_finish: Optional[bool] = ...) -> Scenario:
        """A copy with the given arguments changed."""
        ...
    @property
    def document(self) -> Dict[str, Any]: ...
    @property
    def name(self) -> str: ...
    @property
    def toml(self) -> str: ...
    @property
    def body(self) -> Body: ...
    @property
    def potential(self) -> Dict[str, Any]: ...
    @property
    def position(self) -> npt.NDArray[np.float64]: ...
    @property
    def quaternion(self) -> npt.NDArray[np.float64]:
        """q0 (4,), scalar-first (w, x, y, z)."""
        ...
    @property
    def momentum(self) -> npt.NDArray[np.float64]: ...
    @property
    def velocity(self) -> npt.NDArray[np.float64]: ...
    @property
    def w(self) -> npt.NDArray[np.float64]: ...
    @property
    def omega(self) -> npt.NDArray[np.float64]: ...
    @property
    def step(self) -> float: ...
    @property
    def time_transform(self) -> Literal["none", "potential"]: ...
    @property
    def duration(self) -> float: ...
    @property
    def steps(self) -> int: ...
    @property
    def method(self) -> str: ...
    @property
    def solver(self) -> str: ...
    @property
    def on_contact(self) -> Literal["stop", "warn", "ignore"]: ...
    @property
    def tolerance(self) -> float: ...
    @property
    def max_iterations(self) -> int: ...
    @property
    def predictor_order(self) -> int: ...
    @property
    def order(self) -> int: ...
    @property
    def composition(self) -> Tuple[float, ...]: ...
    @property
    def every(self) -> int: ...
    @property
    def output_format(self) -> str: ...
    @property
    def layout(self) -> Layout: ...
    def evaluate_potential(self, position: Vector3, quaternion: Quaternion
                           ) -> Tuple[float, npt.NDArray[np.float64], npt.NDArray[np.float64]]:
        """(energy, force, torque) of the built-in potential; quaternion scalar-first (w, x, y, z)."""
        ...
    def save(self, path: PathLike) -> PathLike: ...

class BodyTrajectory:
    """One body of a Result at its written steps, the same in either layout."""
    index: int
    name: str
    t: npt.NDArray[np.float64]
    x: npt.NDArray[np.float64]
    q: npt.NDArray[np.float64]
    p: npt.NDArray[np.float64]
    w: npt.NDArray[np.float64]
    quat_norm_error: npt.NDArray[np.float64]

class Result:
    """A run's trajectory, one body or many (numpy arrays; q scalar-first (w, x, y, z)) with its summary dict.
    ``layout`` "single-body": per-body arrays (steps, ...); "long": (steps, N, ...). ``per_body`` and ``body``
    are the same in either."""
    data: npt.NDArray[np.float64]
    columns: Dict[str, npt.NDArray[np.float64]]
    summary: Dict[str, Any]
    scenario_toml: Optional[str]
    source: Optional[str]
    layout: Layout
    names: List[str]
    def __init__(self, data: npt.ArrayLike, summary: Optional[Mapping[str, Any]] = ...,
                 scenario_toml: Optional[str] = ..., source: Optional[str] = ...,
                 columns: Optional[Sequence[str]] = ..., names: Optional[Sequence[str]] = ...,
                 layout: Optional[Layout] = ...) -> None: ...
    @property
    def bodies(self) -> int: ...
    def per_body(self, quantity: Literal["x", "q", "p", "w", "quat_norm_error"]) -> npt.NDArray[np.float64]:
        """(steps, N, 3), (steps, N, 4) or (steps, N) in either layout."""
        ...
    def body(self, which: Union[int, str]) -> BodyTrajectory: ...
    @property
    def t(self) -> npt.NDArray[np.float64]: ...
    @property
    def wheels(self) -> Dict[str, Any]:
        """single-body: wheel name -> {"speed", "momentum", "torque"} -> (steps,) arrays; long: body name ->
        wheel name -> the same; {} without reaction wheels."""
        ...
    @property
    def sensors(self) -> Dict[str, npt.NDArray[np.float64]]:
        """What the controller's sensors read at its samples: name -> (S,) array; {} without sensors."""
        ...
    @property
    def x(self) -> npt.NDArray[np.float64]: ...
    @property
    def q(self) -> npt.NDArray[np.float64]:
        """(steps, 4), or (steps, N, 4) in the long layout; scalar-first (w, x, y, z)."""
        ...
    @property
    def p(self) -> npt.NDArray[np.float64]: ...
    @property
    def w(self) -> npt.NDArray[np.float64]: ...
    @property
    def quat_norm_error(self) -> npt.NDArray[np.float64]: ...
    @property
    def energy(self) -> npt.NDArray[np.float64]: ...
    @property
    def energy_error(self) -> npt.NDArray[np.float64]: ...
    @property
    def L(self) -> npt.NDArray[np.float64]: ...
    @property
    def momentum_error(self) -> npt.NDArray[np.float64]: ...
    @property
    def P(self) -> npt.NDArray[np.float64]: ...
    @property
    def linear_momentum_error(self) -> npt.NDArray[np.float64]: ...
    @property
    def temperature(self) -> npt.NDArray[np.float64]: ...
    @property
    def pressure(self) -> npt.NDArray[np.float64]: ...
    @property
    def omega(self) -> npt.NDArray[np.float64]: ...
    def rotation_matrices(self) -> npt.NDArray[np.float64]: ...
    def euler_angles(self, seq: str = ..., degrees: bool = ...) -> npt.NDArray[np.float64]: ...
    def lvlh_angles(self, degrees: bool = ...) -> npt.NDArray[np.float64]: ...
    @property
    def completed(self) -> bool: ...
    @property
    def error(self) -> str: ...
    def __len__(self) -> int: ...
    def save(self, run_dir: PathLike) -> PathLike: ...
    def draw_figures(self, out_dir: PathLike) -> List[str]: ...  # deprecated: lgvi.plot.draw_figures(result, out_dir)

class SystemResult(Result):
    """Deprecated: a Result of layout "long" (isinstance tells a Result's layout); Result holds both."""
    def __init__(self, data: npt.ArrayLike, summary: Optional[Mapping[str, Any]] = ...,
                 scenario_toml: Optional[str] = ..., source: Optional[str] = ...,
                 columns: Optional[Sequence[str]] = ..., names: Optional[Sequence[str]] = ...) -> None: ...

ForcingFunction = Callable[[float, np.ndarray, np.ndarray, np.ndarray, np.ndarray], Tuple[Any, Any]]

def simulate(scenario: Union[Scenario, PathLike],
             potential: Union[None, PythonPotential, PotentialFunction] = ..., *,
             forcing: Union[None, PythonForcing, ForcingFunction] = ...,
             control: Optional[Callable[[float, npt.NDArray[np.float64], npt.NDArray[np.float64],
                                         npt.NDArray[np.float64]], Any]] = ...,
             check: bool = ...) -> Result:
    """Run a scenario (bit-identical to `lgvi run`); IntegrationError (with .result) on a failed step."""
    ...

class Stepper:
    """One step at a time, for control loops; quaternion scalar-first (w, x, y, z). For N bodies the per-body
    arrays have a leading body axis: (N, 3), (N, 4), (N, 3, 3)."""
    def __init__(self, scenario: Union[Scenario, PathLike],
                 potential: Union[None, PythonPotential, PotentialFunction] = ..., *,
                 forcing: Union[None, PythonForcing, ForcingFunction] = ...) -> None: ...
    @property
    def work(self) -> float: ...
    def step(self, n: int = ...) -> None: ...
    def refresh(self) -> None: ...
    def set_potential(self, potential: Union[None, PythonPotential, PotentialFunction]) -> None: ...
    def set_state(self, position: Optional[npt.ArrayLike] = ..., quaternion: Optional[npt.ArrayLike] = ...,
                  momentum: Optional[npt.ArrayLike] = ..., w: Optional[npt.ArrayLike] = ..., *,
                  velocity: Optional[npt.ArrayLike] = ..., omega: Optional[npt.ArrayLike] = ...) -> None: ...
    @property
    def bodies(self) -> int: ...
    @property
    def scenario(self) -> Scenario: ...
    @property
    def potential(self) -> Union[None, PythonPotential, PotentialFunction]: ...
    @property
    def k(self) -> int: ...
    @property
    def t(self) -> float: ...
    @property
    def h(self) -> float: ...
    @property
    def position(self) -> npt.NDArray[np.float64]: ...
    @property
    def quaternion(self) -> npt.NDArray[np.float64]:
        """(4,) or (N, 4), scalar-first (w, x, y, z)."""
        ...
    @property
    def momentum(self) -> npt.NDArray[np.float64]: ...
    @property
    def velocity(self) -> npt.NDArray[np.float64]: ...
    @property
    def w(self) -> npt.NDArray[np.float64]: ...
    @property
    def omega(self) -> npt.NDArray[np.float64]: ...
    @property
    def rotation_matrix(self) -> npt.NDArray[np.float64]: ...
    @property
    def energy(self) -> float: ...
    @property
    def energy_error(self) -> float: ...
    @property
    def potential_energy(self) -> float: ...
    @property
    def force(self) -> npt.NDArray[np.float64]: ...
    @property
    def torque(self) -> npt.NDArray[np.float64]: ...
    @property
    def angular_momentum(self) -> npt.NDArray[np.float64]: ...
    @property
    def linear_momentum(self) -> npt.NDArray[np.float64]: ...
    @property
    def solver_iterations(self) -> int: ...
    @property
    def row(self) -> npt.NDArray[np.float64]: ...
    @property
    def state(self) -> Dict[str, Any]: ...

def load(path: PathLike) -> Result:
    """A run folder or trajectory file (.csv, .npz, .h5) as a Result, in the trajectory's layout."""
    ...

def load_run(run_dir: PathLike) -> Tuple[Dict[str, npt.NDArray[np.float64]], Dict[str, Any]]: ...

def load_bodies(run_dir: PathLike) -> List[Dict[str, Any]]:
    """A many-body run folder's bodies: set-up and final state, from summary.json or the file it names."""
    ...


class EnsembleResult:
    """The members table of an ensemble: members.csv's text, header and columns."""
    text: str
    header: List[str]
    columns: Dict[str, Any]
    completed: npt.NDArray[np.bool_]
    changes_not_errors: Tuple[str, ...]
    pointing_times: Optional[npt.NDArray[np.float64]]
    pointing_error: Optional[npt.NDArray[np.float64]]
    settle_band_deg: Optional[float]
    def __len__(self) -> int: ...
    def __getitem__(self, name: str) -> Any: ...
    def save(self, path: PathLike) -> None: ...

def ensemble(scenario: Union[Scenario, PathLike], vary: Union[Dict[str, Any], Sequence[Dict[str, Any]]],
             members: Optional[int] = ..., seed: Optional[int] = ..., executor: Any = ...,
             trajectories: str = ..., metrics: Optional[Sequence[str]] = ...,
             settle_band_deg: Optional[float] = ..., sensor_noise: Optional[str] = ...) -> EnsembleResult:
    """Run an ensemble of a scenario with some of its numbers varied (the semantics of `lgvi ensemble`)."""
    ...

def view(source: Union[PathLike, Result], out: Optional[PathLike] = ..., max_frames: int = ...,
         display: bool = ...) -> str:
    """Write the interactive 3-D view of a run (one offline HTML file, default RUN_DIR/view.html); its path.
    In Jupyter it is also displayed inline."""
    ...
