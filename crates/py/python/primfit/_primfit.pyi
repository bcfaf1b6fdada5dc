"""Type stubs of the extension module ``primfit._primfit`` (low level: use ``primfit``).

Arrays must already be float64 (int64 for indices); the ``primfit`` facade converts.
"""

import numpy as np
import numpy.typing as npt

__version__: str

_F64 = npt.NDArray[np.float64]
_I64 = npt.NDArray[np.int64]
_Limit = int | float | str | None

class ChamferProblem:
    def __new__(
        cls,
        cloud: _F64,
        samples: _F64,
        owner: _I64,
        n: int | None = None,
        *,
        model: str = "existence",
        alpha: _Limit = None,
        beta: _Limit = None,
        cap: float = 0.0,
        weights: tuple[float, float] = (1.0, 1.0),
    ) -> ChamferProblem: ...
    @property
    def n_candidates(self) -> int: ...
    @property
    def n_points(self) -> int: ...
    @property
    def n_entries(self) -> int: ...
    @property
    def weights(self) -> tuple[float, float]: ...
    @property
    def g(self) -> _F64: ...
    def evaluate(self, p: _F64) -> tuple[float, float, _F64]: ...
    def evaluate_batch(self, p: _F64) -> tuple[_F64, _F64]: ...

def fit(
    cloud: _F64,
    *,
    types: list[str] | None = None,
    size: float | None = None,
    radius: float | None = None,
    bend: float | None = None,
    spacing: float | None = None,
    origin: list[float] | None = None,
    sample_spacing: float | None = None,
    model: str = "existence",
    alpha: _Limit = None,
    beta: _Limit = None,
    cap: float | None = None,
    weights: tuple[float, float] | None = None,
    parameterization: str = "box",
    max_iterations: int = 200,
    polish: bool = True,
    mesh_model: tuple[_F64, _I64] | None = None,
    seed: int = 0,
    memory_budget: int | None = None,
) -> tuple[str, _F64]: ...
