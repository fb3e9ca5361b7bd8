from typing import Any, Callable, Optional, Tuple

import numpy as np

ForcingFunction = Callable[[float, np.ndarray, np.ndarray, np.ndarray, np.ndarray], Tuple[Any, Any]]

class PythonForcing:
    function: ForcingFunction
    body: Optional[str]
    velocity_dependent: bool
    def __init__(self, function: ForcingFunction, *, body: Optional[str] = ...,
                 velocity_dependent: bool = ...) -> None: ...

def core_forcing(forcing: Any) -> Optional[Tuple[ForcingFunction, Optional[str], bool]]: ...
