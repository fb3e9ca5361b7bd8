"""Type stubs of lgvi.plot: the paper's figures. Quaternions are scalar-first (qw, qx, qy, qz)."""

import os
from typing import Any, Dict, List, Optional, Sequence, Tuple, Union

import numpy as np
import numpy.typing as npt

REQUIRED_COLUMNS: Tuple[str, ...]
DPI: int
FIGSIZE: Tuple[float, float]
N_INSTANTS: int

def load_run(run_dir: Union[str, os.PathLike[str]]) -> Tuple[Dict[str, npt.NDArray[np.float64]], Dict[str, Any]]:
    """(columns, summary) of a run folder."""
    ...
def rotation_matrix(q: npt.ArrayLike) -> npt.NDArray[np.float64]:
    """R = pi(q) of scalar-first (w, x, y, z) quaternions, (4,) -> (3, 3) or (N, 4) -> (N, 3, 3)."""
    ...
def orbit_period(t: npt.ArrayLike, x: npt.ArrayLike, y: npt.ArrayLike) -> Optional[float]: ...
def draw_figures(source: Any, out_dir: Optional[Union[str, os.PathLike[str]]] = ...) -> List[str]:
    """The five PNG figures of a run folder, trajectory file or lgvi.Result."""
    ...
def main(argv: Optional[Sequence[str]] = ...) -> int: ...
