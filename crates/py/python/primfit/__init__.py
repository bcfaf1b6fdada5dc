"""primfit: represent a 3D point cloud with geometric primitives.

The library infers which members of a large, fixed, discrete set of candidate
primitives exist, by minimising a *probabilistic chamfer distance* over their existence
probabilities (see DESIGN.md §2). Everything heavy runs in Rust with the GIL released.

Arrays go in as anything numpy can read (lists, float32, Fortran order, CPU tensors):
they are converted to C-ordered float64 here. Non-numeric arrays (object, str, bool)
raise ``TypeError``; wrong shapes, NaN/inf, empty clouds and out-of-range indices raise
``ValueError``; file problems raise ``OSError``.

Quick start::

    import numpy as np, primfit
    prim, point, grad = primfit.probabilistic_chamfer(cloud, samples, owner, p, cap=0.25)
    result = primfit.fit(cloud, types=["square"], size=1.0)  # as `primfit fit`
    result.primitives[0]["type"], result.existence, result.metrics

The optional PyTorch integration lives in :mod:`primfit.torch` (imported on demand).
"""

from __future__ import annotations

import json
import os
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import numpy.typing as npt

from . import _primfit, synth
from ._convert import _floats, _ints, _points
from ._primfit import __version__

__all__ = [
    "Candidates",
    "ChamferProblem",
    "FitResult",
    "Solution",
    "__version__",
    "candidates",
    "chamfer_problems",
    "fit",
    "probabilistic_chamfer",
    "read_mesh",
    "read",
    "read_ply",
    "register",
    "render",
    "synth",
    "write_mesh",
    "write_ply",
]

ArrayLike = npt.ArrayLike
Limit = int | float | str | None


class ChamferProblem:
    """The probabilistic chamfer distance of one cloud against one candidate set.

    The candidates are given by explicit surface samples: ``samples`` (K, 3) with
    ``owner`` (K,) giving each sample's candidate in ``0..n``. Every candidate needs at
    least one sample. Coefficients (nearest distances, sorted point entries) are built
    once here, so repeated evaluations are pure arithmetic.

    Parameters
    ----------
    cloud : (J, 3) array
        The input points.
    samples : (K, 3) array
        Candidate surface samples.
    owner : (K,) int array
        Candidate index of every sample, in ``0..n``.
    n : int, optional
        Number of candidates N (default ``max(owner) + 1``).
    model : {"existence", "independent"}
        Point-term model (DESIGN §2).
    alpha, beta : int, "inf" or None
        Samples kept per (point, candidate) (``independent`` only) and candidates kept per
        point. ``None`` or ``"inf"`` keeps all: the exact loss.
    cap : float
        ``d_cap`` itself (squared units): the cost of a point no existing candidate explains.
    weights : (float, float)
        Weights of the primitive and point terms; gradients are of the weighted total.
    """

    def __init__(
        self,
        cloud: ArrayLike,
        samples: ArrayLike,
        owner: ArrayLike,
        n: int | None = None,
        *,
        model: str = "existence",
        alpha: Limit = None,
        beta: Limit = None,
        cap: float = 0.0,
        weights: tuple[float, float] = (1.0, 1.0),
    ) -> None:
        self._inner = _primfit.ChamferProblem(
            _points("cloud", cloud),
            _points("samples", samples),
            _ints("owner", owner),
            n,
            model=model,
            alpha=alpha,
            beta=beta,
            cap=float(cap),
            weights=(float(weights[0]), float(weights[1])),
        )

    @classmethod
    def _wrap(cls, inner: _primfit.ChamferProblem) -> ChamferProblem:
        problem = cls.__new__(cls)
        problem._inner = inner
        return problem

    @property
    def n_candidates(self) -> int:
        """Number of candidates N."""
        return self._inner.n_candidates

    @property
    def n_points(self) -> int:
        """Number of cloud points J."""
        return self._inner.n_points

    @property
    def n_entries(self) -> int:
        """Number of stored (point, candidate[, sample]) entries of the point term."""
        return self._inner.n_entries

    @property
    def weights(self) -> tuple[float, float]:
        """``(primitive_weight, point_weight)``."""
        return self._inner.weights

    @property
    def g(self) -> np.ndarray:
        """Primitive-term coefficients ``g_i`` (N,): the primitive term is ``g @ p``."""
        return self._inner.g

    def evaluate(self, p: ArrayLike) -> tuple[float, float, np.ndarray]:
        """``(primitive_term, point_term, grad)`` at probabilities ``p`` (N,).

        The terms are unweighted; ``grad`` (N,) is the gradient of the weighted total
        ``w_prim * primitive_term + w_point * point_term``.
        """
        return self._inner.evaluate(_floats("p", p, 1))

    def evaluate_batch(self, P: ArrayLike) -> tuple[np.ndarray, np.ndarray]:
        """Weighted totals (B,) and their gradients (B, N) for a batch ``P`` (B, N).

        Rows are evaluated in parallel in Rust.
        """
        return self._inner.evaluate_batch(_floats("P", P, 2))

    def solve(
        self, start: ArrayLike | float = 0.5, *, max_iterations: int | None = None, polish: bool = True
    ) -> Solution:
        """Minimises the loss over existence as ``primfit fit`` does (projected L-BFGS,
        threshold at 0.5, discrete polish), from ``start``: one probability for every
        candidate (default 0.5, the fit's start) or an (N,) array, e.g. a network's
        existence as a warm start.
        """
        n = self.n_candidates
        p0 = np.full(n, float(np.asarray(start))) if np.ndim(start) == 0 else _floats("start", start, 1)
        return Solution(**self._inner.solve(p0, max_iterations=max_iterations, polish=polish))

    def __repr__(self) -> str:
        return repr(self._inner)


@dataclass(frozen=True)
class Solution:
    """What :meth:`ChamferProblem.solve` found.

    Attributes
    ----------
    probability : (N,) float64 array
        Existence probabilities at the end of L-BFGS.
    exists : (N,) bool array
        The decision, after thresholding and polish.
    iterations, evaluations : int
        L-BFGS iterations and loss-and-gradient evaluations.
    stop : str
        Why L-BFGS stopped: ``gradient``, ``decrease``, ``iterations`` or ``line_search``.
    history : (iterations + 1,) float64 array
        The weighted loss at the start and after every iteration.
    binary : float
        The weighted loss of the decided scene (``exists`` as 0/1).
    """

    probability: np.ndarray
    exists: np.ndarray
    iterations: int
    evaluations: int
    stop: str
    history: np.ndarray
    binary: float


def chamfer_problems(
    clouds: Sequence[ArrayLike],
    samples: ArrayLike,
    owner: ArrayLike,
    n: int | None = None,
    *,
    model: str = "existence",
    alpha: Limit = None,
    beta: Limit = None,
    cap: float = 0.0,
    weights: tuple[float, float] = (1.0, 1.0),
) -> list[ChamferProblem]:
    """One :class:`ChamferProblem` per cloud, all against the same candidate samples.

    The problems are built in Rust in parallel (GIL released): the way to prepare a
    batch of training scenes for :mod:`primfit.torch`. Parameters as for
    :class:`ChamferProblem`; every cloud must be non-empty.
    """
    inner = _primfit.chamfer_problems(
        [_points(f"clouds[{b}]", c) for b, c in enumerate(clouds)],
        _points("samples", samples),
        _ints("owner", owner),
        n,
        model=model,
        alpha=alpha,
        beta=beta,
        cap=float(cap),
        weights=(float(weights[0]), float(weights[1])),
    )
    return [ChamferProblem._wrap(p) for p in inner]


def probabilistic_chamfer(
    cloud: ArrayLike,
    samples: ArrayLike,
    owner: ArrayLike,
    p: ArrayLike,
    *,
    model: str = "existence",
    alpha: Limit = None,
    beta: Limit = None,
    cap: float = 0.0,
    weights: tuple[float, float] = (1.0, 1.0),
) -> tuple[float, float, np.ndarray]:
    """The probabilistic chamfer distance and its gradient (DESIGN §2), in one call.

    Returns ``(primitive_term, point_term, grad)``; ``N = len(p)`` candidates, owners
    in ``0..N``. See :class:`ChamferProblem` for the parameters; build one instead when
    evaluating the same cloud and candidates repeatedly.
    """
    p = _floats("p", p, 1)
    problem = ChamferProblem(
        cloud, samples, owner, len(p), model=model, alpha=alpha, beta=beta, cap=cap, weights=weights
    )
    return problem.evaluate(p)


class FitResult:
    """The outcome of :func:`fit`.

    Attributes
    ----------
    primitives : list of dict
        The chosen primitives as in ``result.json``: ``type``, ``size``, ``pose``
        (``translation``, ``rotation`` quaternion ``[w, x, y, z]``, ``scale``),
        ``existence``; a ``"plane"`` also has ``outline`` ``[[x, y], ...]`` and
        ``holes`` ``[[[x, y], ...], ...]`` in its local frame (z = 0), and, when it
        was seen in several disjoint pieces, ``more_parts``
        ``[{"outline": ..., "holes": ...}, ...]`` beside its largest part.
    existence : (P,) float64 array
        Continuous existence probability of each chosen primitive.
    metrics : dict
        The measures of DESIGN §4 of the fit against its cloud.
    settings : dict
        Every setting used, defaults included.
    """

    def __init__(self, document: str, existence: np.ndarray) -> None:
        self._document = document
        doc = json.loads(document)
        self.primitives: list[dict[str, Any]] = doc["primitives"]
        self.metrics: dict[str, Any] = doc["metrics"]
        self.settings: dict[str, Any] = doc["settings"]
        self.existence: np.ndarray = existence

    @classmethod
    def from_json(cls, document: str | Mapping[str, Any]) -> FitResult:
        """A fit's result read back from its ``result.json`` (the text, or the parsed
        dict), e.g. one ``primfit fit -o`` wrote. It is checked against the library's
        schema (settings, metrics, primitives; mesh sources must be readable files):
        anything else raises ``ValueError``."""
        text = document if isinstance(document, str) else json.dumps(document, indent=2)
        return cls(text, _primfit.read_result(text))

    def to_json(self) -> str:
        """The ``result.json`` document (DESIGN §3), as the CLI writes it."""
        return self._document

    def to_mesh(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The primitives as one triangle mesh, as ``primfit fit --mesh`` exports it:
        ``(vertices (V, 3) float64, faces (F, 3) int64, primitive (F,) int64)``, where
        ``primitive[f]`` is the index in :attr:`primitives` of face ``f``'s primitive."""
        return _primfit.primitives_mesh(_primitive_list(self))

    def to_trimesh(self) -> Any:
        """The mesh of :meth:`to_mesh` as a ``trimesh.Trimesh`` (vertices as given, no
        merging), with ``face_attributes["primitive"]``. Needs the ``trimesh`` package,
        imported here: ``ImportError`` names it when it is missing."""
        trimesh = _optional("trimesh")
        vertices, faces, owner = self.to_mesh()
        return trimesh.Trimesh(
            vertices=vertices, faces=faces, face_attributes={"primitive": owner}, process=False
        )

    def to_open3d(self) -> Any:
        """The mesh of :meth:`to_mesh` as an ``open3d.geometry.TriangleMesh``. Needs the
        ``open3d`` package, imported here: ``ImportError`` names it when it is missing."""
        o3d = _optional("open3d")
        vertices, faces, _ = self.to_mesh()
        return o3d.geometry.TriangleMesh(
            o3d.utility.Vector3dVector(vertices), o3d.utility.Vector3iVector(faces.astype(np.int32))
        )

    def __len__(self) -> int:
        return len(self.primitives)

    def __repr__(self) -> str:
        kinds: dict[str, int] = {}
        for q in self.primitives:
            kinds[q["type"]] = kinds.get(q["type"], 0) + 1
        summary = ", ".join(f"{n} {k}" for k, n in sorted(kinds.items())) or "none"
        return f"FitResult({len(self.primitives)} primitives: {summary})"


def _fit_options(options: dict[str, Any]) -> _primfit.FitOptions:
    """The options of :func:`fit` as the extension's ``FitOptions``; a mesh given as
    arrays is converted here (its keyword list is the extension's, see ``_primfit.pyi``)."""
    mesh = options.get("mesh_model")
    if isinstance(mesh, tuple):
        vertices, faces = mesh
        mesh = (_points("mesh vertices", vertices), _ints("mesh faces", faces, 2))
        options = {**options, "mesh_model": mesh}
    return _primfit.FitOptions(**options)


def _optional(name: str) -> Any:
    """The optional package ``name``, imported on demand."""
    import importlib

    try:
        return importlib.import_module(name)
    except ImportError as e:
        raise ImportError(f"this needs the optional package {name!r} (pip install {name})") from e


def _cloud(cloud: ArrayLike | Mapping[str, Any]) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    """The points of ``cloud`` and, for a dict as :func:`read_ply` returns, the per-point
    ``normals``, ``labels`` and ``sensors`` it has. An object with a ``points``
    attribute (an Open3D ``PointCloud``) gives its points, and its ``normals`` when its
    ``has_normals()`` says so."""
    if not isinstance(cloud, Mapping) and hasattr(cloud, "points") and not isinstance(cloud, np.ndarray):
        o3d_cloud: Any = cloud
        extra: dict[str, np.ndarray] = {}
        if getattr(o3d_cloud, "has_normals", lambda: False)():
            extra["normals"] = _points("cloud normals", np.asarray(o3d_cloud.normals))
        return _points("cloud", np.asarray(o3d_cloud.points)), extra
    if not isinstance(cloud, Mapping):
        return _points("cloud", cloud), {}
    extra = {}
    for name in ("normals", "sensors"):
        if cloud.get(name) is not None:
            extra[name] = _points(name, cloud[name])
    if cloud.get("labels") is not None:
        extra["labels"] = np.ascontiguousarray(_ints("labels", cloud["labels"]), dtype=np.int32)
    return _points("cloud", cloud["points"]), extra


def fit(cloud: ArrayLike | Mapping[str, Any], **options: Any) -> FitResult:
    """Fits primitives to ``cloud``, as ``primfit fit`` does: with no options,
    ``fit(read_ply(path))`` gives the primitives of ``primfit fit path``.

    ``cloud`` is a (J, 3) array-like, an Open3D ``PointCloud`` (any object with a
    ``points`` attribute), or a dict as :func:`read_ply` returns (its ``normals``,
    ``labels`` and ``sensors`` are used by ``method="mcmc"``; ``sensors`` also by
    ``free_space``). Every option is a flag of
    ``primfit fit`` under the same name (``--no-refine`` is ``refine=False``,
    ``--no-polish`` is ``polish=False``); ``None`` or leaving it out takes the library's
    default or derives the value from the cloud (the result's ``settings`` lists what was
    used). The keywords and their types are those of ``primfit._primfit.FitOptions``.

    Parameters
    ----------
    types : list of str or comma-separated str
        ``"auto"`` (the default: the compact model, planes with outlines, cylinders and
        spheres detected in the data; the lattice options play no part), or lattice types
        from square, disk, cylinder, elbow, sphere, mesh.
    size, radius, bend, spacing : float
        Candidate main extent (default: bounding-box diagonal / 8, rounded down to 1, 2 or
        5 × 10^k), tube radius (size / 10), elbow bend radius (spacing), lattice step
        (size / 2), in scene units.
    origin : (3,) floats
        A lattice point (default: with ``frame="axis"`` the scene origin, otherwise grid
        planes on the scan's main planes).
    frame : "auto", "axis", dict or str
        Lattice frame: ``"auto"`` (default) estimates the scan's dominant axes, ``"axis"``
        uses the scene axes; a dict ``{"rotation": [w, x, y, z], "origin": [x, y, z]}``
        (origin optional) or a ``result.json`` document (or the path of a JSON file) gives
        it.
    refine : bool
        Continuous refinement of the chosen primitives (default True).
    refine_rounds : int
        Refinement rounds (default 4).
    sample_spacing : float
        Spacing of candidate surface samples (default min(size / 16, 2π·radius / 12), at
        least the cloud's median point spacing).
    model : {"existence", "independent"}
        Point-term model (default existence).
    alpha, beta : int or "inf"
        Samples per (point, candidate), independent model only, and candidates per point
        (defaults 10 and 32).
    cap : float
        The distance (not squared) whose square is ``d_cap`` (default max(spacing, 5σ)
        with σ the cloud's noise level).
    weights : (float, float)
        Weights of the primitive and point terms (default 1, 1).
    method : {"chamfer", "mcmc"}
        Inference method (default chamfer); mcmc needs the cloud's ``sensors``.
    steps, burn_in, noise_rate, sigma, prior
        Options of ``method="mcmc"`` (defaults max(1000, 20 × candidates), steps / 5,
        1 / bounding-box diagonal, spacing / 10, 0.1).
    parameterization : {"box", "logit"}
        Existence parameterisation of L-BFGS (default box).
    max_iterations : int
        L-BFGS iterations at most (default 200).
    search_points : int or "inf"
        Clouds of more points are solved in two phases (default 50000; 0 or "inf": one).
    polish : bool
        Run the discrete polish after thresholding (default True).
    seed : int
        Seed for every random choice (default 0).
    mesh_model : path or (vertices (V, 3), faces (F, 3) int)
        The triangle mesh of the ``mesh`` type (a PLY file, or e.g. :func:`read_mesh`).
    memory_budget : int
        Upper bound on the fit's estimated peak memory in bytes (default half the
        machine's memory).
    work_budget : float
        Upper bound on a lattice pass's estimated work, in nearest-neighbour queries
        per point (default 2000, 20x the default lattice fit's); a fit over either
        budget raises ``ValueError`` before it starts. Ctrl-C stops a running fit
        (``KeyboardInterrupt``) at its next stage.
    free_space : bool
        Charge each candidate for the rays that cross it in front of their points
        (``--free-space``; default: on exactly when the cloud has ``sensors``;
        ``True`` without them is an error).
    """
    points, extra = _cloud(cloud)
    return FitResult(*_primfit.fit(points, _fit_options(options), **extra))


def register(
    cloud: ArrayLike | Mapping[str, Any],
    model: str | os.PathLike[str] | tuple[ArrayLike, ArrayLike],
    *,
    count: int | None = None,
    min_confidence: float | None = None,
    rotation_only: bool = False,
    scale: tuple[float, float] | None = None,
    seed: int = 0,
) -> FitResult:
    """Finds the object ``model`` in ``cloud``, as ``primfit register`` does: the full
    pose (rotation and translation) of each copy, with its calibrated existence.

    ``cloud`` as for :func:`fit`; a dict from :func:`read_ply` with ``sensors`` (per-point
    sensor origins) turns on the visibility test and its calibration. ``model`` is a PLY
    mesh path, or ``(vertices (V, 3), faces (F, 3) int)`` (e.g. :func:`read_mesh`; the
    result's mesh ``source`` is then ``"python"`` and :meth:`FitResult.to_mesh` needs a
    path). With ``count`` unset every copy whose existence reaches ``min_confidence``
    (default 0.5) is reported and the search stops at the first that does not; with
    ``count`` that many are searched for and those below ``min_confidence`` left out.
    ``rotation_only`` keeps the translation at the origin; ``scale=(lo, hi)`` also
    searches a scale in that range. The result's primitives are ``"type": "mesh"``
    entries with ``pose``, ``existence``, ``margin`` (over clutter) and
    ``inlier_share``. Raises ``ValueError`` for a bad option or input, ``OSError`` for
    an unreadable model; Ctrl-C stops it (``KeyboardInterrupt``).
    """
    points, extra = _cloud(cloud)
    if isinstance(model, tuple):
        mesh: Any = (_points("model vertices", model[0]), _ints("model faces", model[1], 2))
    else:
        mesh = os.fspath(model)
    document, existence = _primfit.register(
        points, mesh, sensors=extra.get("sensors"), count=count, min_confidence=min_confidence,
        rotation_only=rotation_only, scale=scale, seed=seed,
    )
    return FitResult(document, existence)


class Candidates:
    """The candidate set a :func:`fit` would optimise over, as explicit samples.

    Attributes
    ----------
    samples : (K, 3) float64 array
        Every candidate's surface samples, in scene coordinates.
    owner : (K,) int64 array
        The candidate of each sample, in ``0..N``.
    primitives : list of dict
        The N candidates, in the ``result.json`` format.
    settings : dict
        Every setting the fit would use (sizes, ``cap`` as a distance, ``alpha``, ...).
    """

    def __init__(self, cloud: np.ndarray, options: _primfit.FitOptions) -> None:
        settings, samples, owner, primitives = _primfit.candidates(cloud, options)
        self._cloud, self._options = cloud, options
        self.settings: dict[str, Any] = json.loads(settings)
        self.samples: np.ndarray = samples
        self.owner: np.ndarray = owner
        self.primitives: list[dict[str, Any]] = json.loads(primitives)

    def __len__(self) -> int:
        return len(self.primitives)

    def problem(self) -> ChamferProblem:
        """The loss the fit minimises, as a :class:`ChamferProblem` over these candidates
        (same model, alpha, beta, cap, weights, and distances to the candidates' exact
        surfaces where the fit uses them), built from the lattice rather than from
        :attr:`samples`."""
        return ChamferProblem._wrap(_primfit.fit_problem(self._cloud, self._options))

    def __repr__(self) -> str:
        return f"Candidates({len(self)} candidates, {len(self.samples)} samples)"


def candidates(cloud: ArrayLike, **options: Any) -> Candidates:
    """The candidates (lattice after the occupancy prior) that ``fit(cloud, **options)``
    would optimise over; ``options`` are those of :func:`fit`.

    :meth:`Candidates.problem` gives the fit's loss, e.g. to run another optimiser on it.
    """
    return Candidates(_points("cloud", cloud), _fit_options(options))


def read_ply(path: str | os.PathLike[str]) -> dict[str, np.ndarray]:
    """Reads a PLY point cloud (ascii or binary; float, double or integer coordinates).

    Returns a dict with ``points`` (J, 3) float64 and, when the file has them,
    ``normals`` (J, 3) float64, ``colors`` (J, 3) uint8, ``labels`` (J,) int32 and
    ``sensors`` (J, 3) float64 (per-point sensor origins). Points with a NaN or infinite
    coordinate are dropped. Raises ``OSError`` (cannot open) or ``ValueError`` (not a
    valid PLY file).
    """
    return _primfit.read_ply(os.fspath(path))


def write_ply(
    path: str | os.PathLike[str],
    points: ArrayLike,
    *,
    normals: ArrayLike | None = None,
    colors: ArrayLike | None = None,
    labels: ArrayLike | None = None,
    sensors: ArrayLike | None = None,
    ascii: bool = False,
) -> None:
    """Writes a PLY point cloud atomically (binary little-endian unless ``ascii``).

    ``points``, ``normals`` and ``sensors`` are (J, 3) and written as double; ``colors``
    (J, 3) integers in 0..255; ``labels`` (J,) integers. :func:`read_ply` reads it back
    exactly.
    """

    def ints(name: str, x: ArrayLike, ndim: int, dtype: type) -> np.ndarray:
        a = _ints(name, x, ndim)
        info = np.iinfo(dtype)
        if a.size and (a.min() < info.min or a.max() > info.max):
            raise ValueError(f"{name} must be in {info.min}..{info.max}")
        return np.ascontiguousarray(a, dtype=dtype)

    _primfit.write_ply(
        os.fspath(path),
        _points("points", points),
        normals=None if normals is None else _points("normals", normals),
        colors=None if colors is None else ints("colors", colors, 2, np.uint8),
        labels=None if labels is None else ints("labels", labels, 1, np.int32),
        sensors=None if sensors is None else _points("sensors", sensors),
        ascii=ascii,
    )


read = read_ply
"""Reads a point cloud of any supported format (PLY, PCD, LAS/LAZ, E57, XYZ/PTS/CSV),
chosen by extension and checked by content: an alias of :func:`read_ply`."""


def read_mesh(path: str | os.PathLike[str]) -> tuple[np.ndarray, np.ndarray]:
    """Reads a PLY triangle mesh: ``(vertices (V, 3) float64, faces (F, 3) int64)``.

    Polygons are fan-triangulated. The result can be passed as ``fit(mesh_model=...)``.
    """
    return _primfit.read_mesh(os.fspath(path))


def _primitive_list(primitives: FitResult | Sequence[dict[str, Any]]) -> str:
    """Primitives as the JSON list the extension reads."""
    if isinstance(primitives, FitResult):
        primitives = primitives.primitives
    return json.dumps(list(primitives))


def write_mesh(
    path: str | os.PathLike[str],
    primitives: FitResult | Sequence[dict[str, Any]],
    *,
    ascii: bool = False,
) -> None:
    """Writes primitives (a :class:`FitResult` or dicts as in ``result.json``) as one
    triangle mesh, as ``primfit fit --mesh`` does, in the format of the path's extension:

    - ``.ply``: per-face ``primitive`` index, palette vertex colours (``ascii`` or binary);
    - ``.obj``: one object ``primitive_K_TYPE`` per primitive, vertex colours;
    - ``.glb`` (glTF binary): one node and mesh per primitive with a palette material,
      ``{"index", "type", "existence"}`` in the node's ``extras``.

    Any other extension raises ``ValueError`` naming the path; nothing is written on error.
    """
    _primfit.write_mesh(os.fspath(path), _primitive_list(primitives), ascii=ascii)


def render(
    path: str | os.PathLike[str],
    cloud: ArrayLike | Mapping[str, Any],
    primitives: FitResult | Sequence[dict[str, Any]],
    *,
    size: tuple[int, int] = (1200, 900),
    view: tuple[float, float] | None = None,
    scale: float | None = None,
) -> float:
    """Draws ``cloud`` and the primitives as a PNG at ``path``, as ``primfit render``:
    points coloured by their distance to the model (viridis, 0 to ``scale`` scene units;
    default: the 95th percentile of the distances), primitives Lambert-shaded in their
    palette colours, an orthographic view fitted to the points.

    ``size`` is ``(width, height)`` in pixels (16 to 8192); ``view`` is
    ``(azimuth, elevation)`` in degrees about the scene's +z axis (matplotlib's
    ``azim, elev``; default: from above and in front of the cloud's principal axes).
    ``cloud`` is a (J, 3) array or a dict as :func:`read_ply` returns. Returns the
    distance at the top of the colour scale.
    """
    points, _ = _cloud(cloud)
    width, height = size
    return _primfit.render(
        os.fspath(path),
        points,
        _primitive_list(primitives),
        width=int(width),
        height=int(height),
        view=None if view is None else (float(view[0]), float(view[1])),
        scale=None if scale is None else float(scale),
    )
