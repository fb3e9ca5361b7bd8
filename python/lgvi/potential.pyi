"""Type stubs of lgvi.potential. Quaternions are scalar-first (w, x, y, z)."""

from typing import Any, Callable, Dict, Optional, Sequence, Tuple, Union

import numpy as np
import numpy.typing as npt

KINDS: Tuple[str, ...]
CENTRAL_MODELS: Tuple[str, ...]

Vector3 = Union[Sequence[float], npt.NDArray[np.float64]]
#: x (3,), q (4,) scalar-first (w, x, y, z)
Function = Callable[[npt.NDArray[np.float64], npt.NDArray[np.float64]], Any]

def none() -> Dict[str, Any]:
    """The free body, {"kind": "none"}."""
    ...
def central(mu: float, stop_at_contact: bool = ..., j2: Optional[float] = ..., reference_radius: Optional[float] = ...,
            pole: Optional[Sequence[float]] = ..., model: str = ...) -> Dict[str, Any]:
    """Central gravity, {"kind": "central", "mu": mu}; model "extended" (default) or "point"."""
    ...
def heavy_top(g: Vector3, pivot_to_com: Vector3) -> Dict[str, Any]:
    """A heavy top about a fixed pivot, {"kind": "heavy-top", "g": [...], "pivot_to_com": [...]}."""
    ...
def uniform(g: Vector3) -> Dict[str, Any]:
    """Uniform gravity, {"kind": "uniform", "g": [gx, gy, gz]}."""
    ...
def spec(potential: Any, name: str = ...) -> Dict[str, Any]: ...
def core_potential(potential: Any, name: str = ...) -> Any: ...

class PythonPotential:
    """A potential written in Python: function(x, q) -> (energy, force, torque), q scalar-first (w, x, y, z)."""
    function: Optional[Function]
    energy: Optional[Function]
    force: Optional[Function]
    torque: Optional[Function]
    def __init__(self, function: Optional[Function] = ..., *, energy: Optional[Function] = ...,
                 force: Optional[Function] = ..., torque: Optional[Function] = ...) -> None: ...
    def __call__(self, x: npt.NDArray[np.float64], q: npt.NDArray[np.float64]) -> Tuple[Any, Any, Any]: ...
    def check(self, position: Vector3, quaternion: Vector3, *, tolerance: float = ...,
              strict: bool = ...) -> Dict[str, Any]:
        """Force/torque errors against finite differences of the energy, their tolerances, ``passed`` and
        ``likely_mistake``; ``strict=True`` raises ValueError unless passed."""
        ...
