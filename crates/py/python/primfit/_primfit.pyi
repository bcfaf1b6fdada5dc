"""Type stubs of the extension module ``primfit._primfit`` (low level: use ``primfit``).

Arrays must already be float64 (int64 for indices); the ``primfit`` facade converts.
"""

import os

from collections.abc import Mapping, Sequence
from typing import Any, final

import numpy as np
import numpy.typing as npt

__all__ = [
    "ChamferProblem",
    "FitOptions",
    "__version__",
    "candidates",
    "chamfer_problems",
    "fit",
    "fit_problem",
    "fit_tile",
    "merge_tiles",
    "primitives_mesh",
    "read_mesh",
    "read_ply",
    "read_result",
    "register",
    "render",
    "spilled_tile_points",
    "split_survey",
    "synth_hallway",
    "synth_nine_cylinders",
    "synth_pipe",
    "synth_partial_view",
    "synth_registration",
    "synth_six_in_a_row",
    "tile_grid_array",
    "tile_grid_file",
    "tile_points",
    "write_mesh",
    "write_ply",
]

__version__: str

_F64 = npt.NDArray[np.float64]
_I64 = npt.NDArray[np.int64]
_Limit = int | float | str | None

@final
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
        weights: tuple[float, float] = ...,  # (1.0, 1.0)
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
    def solve(
        self, start: _F64, *, max_iterations: int | None = None, polish: bool = True
    ) -> dict[str, Any]: ...

def chamfer_problems(
    clouds: list[_F64],
    samples: _F64,
    owner: _I64,
    n: int | None = None,
    *,
    model: str = "existence",
    alpha: _Limit = None,
    beta: _Limit = None,
    cap: float = 0.0,
    weights: tuple[float, float] = ...,  # (1.0, 1.0)
) -> list[ChamferProblem]: ...

@final
class FitOptions:
    """Every option of ``primfit fit``, under its name; ``None`` = the library's default."""

    def __new__(
        cls,
        *,
        types: str | Sequence[str] | None = None,
        size: float | None = None,
        radius: float | None = None,
        bend: float | None = None,
        spacing: float | None = None,
        origin: Sequence[float] | npt.ArrayLike | None = None,
        frame: str | Mapping[str, Any] | None = None,
        refine: bool | None = None,
        refine_rounds: int | None = None,
        sample_spacing: float | None = None,
        model: str | None = None,
        alpha: _Limit = None,
        beta: _Limit = None,
        cap: float | None = None,
        weights: Sequence[float] | npt.ArrayLike | None = None,
        method: str | None = None,
        steps: int | None = None,
        burn_in: int | None = None,
        noise_rate: float | None = None,
        sigma: float | None = None,
        prior: float | None = None,
        parameterization: str | None = None,
        max_iterations: int | None = None,
        search_points: _Limit = None,
        polish: bool | None = None,
        seed: int | None = None,
        mesh_model: str | os.PathLike[str] | tuple[_F64, _I64] | None = None,
        memory_budget: int | None = None,
        work_budget: float | None = None,
        free_space: bool | None = None,
    ) -> FitOptions: ...

def fit(
    cloud: _F64,
    options: FitOptions,
    *,
    normals: _F64 | None = None,
    labels: npt.NDArray[np.int32] | None = None,
    sensors: _F64 | None = None,
) -> tuple[str, _F64]: ...
def register(
    cloud: _F64,
    model: str | tuple[_F64, _I64],
    *,
    sensors: _F64 | None = None,
    count: int | None = None,
    min_confidence: float | None = None,
    rotation_only: bool = False,
    scale: tuple[float, float] | None = None,
    seed: int = 0,
) -> tuple[str, _F64]: ...
def read_result(text: str) -> _F64: ...
def candidates(cloud: _F64, options: FitOptions) -> tuple[str, _F64, _I64, str]: ...
def fit_problem(cloud: _F64, options: FitOptions) -> ChamferProblem: ...
def tile_grid_file(
    path: str | os.PathLike[str], tile_size: float | None = None, halo: float | None = None
) -> tuple[str, int]: ...
def tile_grid_array(cloud: _F64, tile_size: float | None = None, halo: float | None = None) -> str: ...
def tile_points(path: str | os.PathLike[str], grid: str, tile: int) -> _F64: ...
def split_survey(
    path: str | os.PathLike[str], grid: str, first: int, count: int, dir: str | os.PathLike[str], part: int
) -> list[int]: ...
def spilled_tile_points(dir: str | os.PathLike[str], tile: int, parts: int) -> _F64: ...
def fit_tile(points: _F64, grid: str, tile: int, options: FitOptions) -> str: ...
def merge_tiles(tiles_json: Sequence[str]) -> tuple[str, _F64]: ...

_Scene = tuple[_F64, str]

def synth_hallway(
    *, length: float = 10.0, width: float = 2.0, height: float = 2.5, side: float = 1.0, ceiling: bool = False,
    density: float | None = None, points: int | None = None, jitter: float = 0.01, drift: float = 0.0,
    offset: float = 0.0, angle: float = 0.0, seed: int = 0,
) -> _Scene: ...
def synth_pipe(
    *, segments: int = 4, max_run: int = 3, segment_length: float = 1.0, bend: float | None = None,
    radius: float | None = None, density: float | None = None, points: int | None = None, jitter: float = 0.005,
    drift: float = 0.0, offset: float = 0.0, angle: float = 0.0, seed: int = 0,
) -> _Scene: ...
def synth_nine_cylinders(
    *, mask: int = 511, pitch: float = 1.0, radius: float = 0.2, height: float = 1.0, density: float | None = None,
    points: int | None = None, jitter: float = 0.01, drift: float = 0.01, offset: float = 0.0, seed: int = 0,
) -> _Scene: ...
def synth_six_in_a_row(
    *, variant: str = "squares", first: float = 7.0, step: float = 1.0, true_index: int = 3, size: float = 1.0,
    points: int = 500, jitter: float = 0.01, seed: int = 0,
) -> _Scene: ...
def synth_registration(
    *, mesh: tuple[_F64, _I64] | None = None, inliers: int = 100, outliers: int = 1900, translation: float = 0.0,
    scale: tuple[float, float] | None = None, outlier_box: float = 1.0, jitter: float = 0.0, seed: int = 0,
) -> _Scene: ...
def synth_partial_view(
    *, mesh: tuple[_F64, _I64] | None = None, inliers: int = 400, outliers: int = 3600, clutter_points: int = 0,
    plane: bool = False, distractors: int = 0, object: bool = True, translation: float = 0.0,
    range_noise: float = 0.0, outlier_box: float = 1.0, seed: int = 0,
) -> _Scene: ...

def read_ply(path: str | os.PathLike[str]) -> dict[str, npt.NDArray[np.generic]]: ...
def write_ply(
    path: str | os.PathLike[str],
    points: _F64,
    *,
    normals: _F64 | None = None,
    colors: npt.NDArray[np.uint8] | None = None,
    labels: npt.NDArray[np.int32] | None = None,
    sensors: _F64 | None = None,
    ascii: bool = False,
) -> None: ...
def read_mesh(path: str | os.PathLike[str]) -> tuple[_F64, _I64]: ...
def write_mesh(path: str | os.PathLike[str], primitives_json: str, *, ascii: bool = False) -> None: ...
def primitives_mesh(primitives_json: str) -> tuple[_F64, _I64, _I64]: ...
def render(
    path: str | os.PathLike[str],
    cloud: _F64,
    primitives_json: str,
    *,
    width: int = 1200,
    height: int = 900,
    view: tuple[float, float] | None = None,
    scale: float | None = None,
) -> float: ...
