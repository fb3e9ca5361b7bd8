"""Type stubs of lgvi._core (private: use `import lgvi`). Quaternions are scalar-first (w, x, y, z)."""

from typing import Any, Dict, List, Optional, Tuple

import numpy as np
import numpy.typing as npt

__version__: str
TRAJECTORY_HEADER: str
BODIES_TRAJECTORY_HEADER: str
FORCED_TRAJECTORY_HEADER: str
FORCED_BODIES_TRAJECTORY_HEADER: str
METHODS: Tuple[str, ...]
SOLVERS: Tuple[str, ...]
FORMATS: Tuple[str, ...]
FORMAT_FILES: Dict[str, Tuple[str, bool]]
INTERACTIONS: Tuple[str, ...]
INTERACTION_KEYS: Dict[str, Tuple[str, ...]]
Array = npt.NDArray[np.float64]

class IntegrationError(RuntimeError):
    step: int
    time: float
    result: Any

class Body:
    def __init__(self, mass: float, inertia: Any) -> None: ...
    @staticmethod
    def from_balls(balls: Any) -> Body: ...
    mass: float
    inertia: Array
    inertia_inverse: Array
    rotational_dof: int
    linear_axis: Array
    balls: List[Dict[str, Any]]

class Scenario:
    name: str
    toml: str
    body: Body
    body_names: List[str]
    potential_kind: str
    mu: float
    g: Array
    position: Array
    quaternion: Array
    momentum: Array
    w: Array
    step: float
    duration: float
    steps: int
    method: str
    solver: str
    tolerance: float
    max_iterations: int
    predictor_order: int
    order: int
    composition: List[float]
    every: int
    output_format: str
    layout: str
    def evaluate_potential(self, position: Any, quaternion: Any) -> Tuple[float, Array, Array]: ...

def check_quaternion(q: npt.ArrayLike, name: str) -> None: ...
def toml_text(document: Dict[str, Any]) -> str: ...
def parse_scenario(text: str, name: str) -> Scenario: ...
def read_scenario(path: str) -> Scenario: ...
def simulate(scenario: Scenario, potential: Any = ..., forcing: Any = ...,
             control: Any = ...
             ) -> Tuple[Array, str, bool, str, Dict[str, Tuple[List[str], Array]], List[str]]:
    """(rows, summary JSON, completed, error, side tables {file: (columns, rows)}, the trajectory's columns)."""
    ...
def check_potential(potential: Any, position: Any, quaternion: Any) -> Tuple[float, float]: ...

class Stepper:
    def __init__(self, scenario: Scenario, potential: Any = ..., forcing: Any = ...) -> None: ...
    @property
    def work(self) -> float: ...
    def step(self, n: int = ...) -> None: ...
    def refresh(self) -> None: ...
    def set_potential(self, potential: Any) -> None: ...
    def set_state(self, position: Optional[Any] = ..., quaternion: Optional[Any] = ...,
                  momentum: Optional[Any] = ..., w: Optional[Any] = ...) -> None: ...
    def row(self) -> Array: ...
    bodies: int
    masses: Array
    inertias: Array
    k: int
    t: float
    h: float
    position: Array
    quaternion: Array
    momentum: Array
    w: Array
    omega: Array
    velocity: Array
    rotation_matrix: Array
    energy: float
    initial_energy: float
    initial_angular_momentum: Array
    potential_energy: float
    force: Array
    torque: Array
    angular_momentum: Array
    linear_momentum: Array
    solver_iterations: int
    python_potential: bool

class EnsemblePlan:
    header: str
    members: int
    scenario_name: str
    def varied(self, i: int) -> List[float]: ...
    def member_toml(self, i: int) -> str: ...
    changes_not_errors: List[str]
    metrics: List[str]
    settle_band_deg: float
    series_times: List[float]
    def split_row(self, row: str) -> Tuple[str, str]: ...

def ensemble_plan(sweep_text: str, name: str, scenario_text: str) -> EnsemblePlan: ...
def run_member(index: int, varied: List[float], scenario_toml: str, scenario_name: str,
               metrics: List[str] = ..., settle_band_deg: float = ...) -> str: ...
