"""The nine-cylinder scenes of thesis §5.5, as training data for :mod:`primfit.research.nn`.

Nine vertical cylinders (candidate k at ``((k % 3 - 1) * pitch, (k // 3 - 1) * pitch, 0)``)
are the whole candidate set; a scene is one of the 2⁹ = 512 subsets (bit k of ``mask``
keeps cylinder k) sampled with per-point ``jitter`` and per-cylinder ``drift``, and
optionally shifted by the alignment ``offset`` (in pitches, thesis figure 5-2). Every
scene has exactly ``points`` points so scenes batch into one tensor.

The self-supervised loss of a scene is the probabilistic chamfer distance of its cloud
against the nine candidates' samples: one :class:`primfit.ChamferProblem` per scene,
built in Rust in one parallel call (:func:`primfit.chamfer_problems`).

Conventions (documented defaults, see :class:`SceneSpec`):

* ``cap`` (``d_cap``, squared) is ``(pitch / 2)²``: a cloud point half a pitch from every
  existing cylinder's samples is as bad as an unexplained one.
* ``weights`` are ``(1 / samples, 9 / points)``: the primitive term is averaged over each
  candidate's samples, the point term over the points one cylinder gets in a full scene.
  With this balance the binary existence vector of least loss is the true mask for
  every aligned scene (tested).
* The empty scene (mask 0) has no points. Its network input is ``points`` copies of the
  grid centre (which lies on no cylinder), and its loss is ``Σ_i p_i g_i`` with
  ``g_i = samples · cap``: every sample of an existing candidate is unexplained
  (:class:`EmptyScene`).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace

import numpy as np

from .. import ChamferProblem, chamfer_problems
from ..synth import nine_cylinders

__all__ = [
    "N_CANDIDATES",
    "EmptyScene",
    "NineScenes",
    "SceneSpec",
    "all_masks",
    "bits",
    "candidate_centres",
    "candidate_samples",
    "make_scenes",
    "masks_with",
    "multi_masks",
    "pair_masks",
    "single_masks",
    "with_offset",
]

N_CANDIDATES = 9
N_SUBSETS = 1 << N_CANDIDATES


@dataclass(frozen=True)
class SceneSpec:
    """How scenes are sampled and scored.

    Attributes
    ----------
    points : int
        Points per scene (every scene the same, so they batch).
    samples : int
        Surface samples per candidate cylinder (the chamfer loss's σ_i).
    pitch, radius, height : float
        Grid pitch and cylinder size (scene units).
    jitter, drift : float
        σ of per-point and per-cylinder noise.
    offset : float
        Largest alignment offset, in pitches (0 = aligned).
    """

    points: int = 256
    samples: int = 64
    pitch: float = 1.0
    radius: float = 0.2
    height: float = 1.0
    jitter: float = 0.01
    drift: float = 0.01
    offset: float = 0.0

    @property
    def cap(self) -> float:
        """``d_cap`` (squared): ``(pitch / 2)²``."""
        return (0.5 * self.pitch) ** 2

    @property
    def weights(self) -> tuple[float, float]:
        """Loss weights ``(1 / samples, 9 / points)``."""
        return 1.0 / self.samples, N_CANDIDATES / self.points


def all_masks() -> np.ndarray:
    """All 512 subsets, 0..511."""
    return np.arange(N_SUBSETS)


def masks_with(counts: Sequence[int]) -> np.ndarray:
    """The masks whose number of cylinders is in ``counts``, ascending."""
    popcount = np.array([bin(m).count("1") for m in range(N_SUBSETS)])
    return np.flatnonzero(np.isin(popcount, list(counts)))


def single_masks() -> np.ndarray:
    """The 9 one-cylinder scenes."""
    return masks_with([1])


def pair_masks() -> np.ndarray:
    """The 36 two-cylinder scenes."""
    return masks_with([2])


def multi_masks() -> np.ndarray:
    """The 502 scenes with at least two cylinders."""
    return masks_with(range(2, N_CANDIDATES + 1))


def bits(masks: np.ndarray) -> np.ndarray:
    """``(S, 9)`` 0/1 float array: bit k of each mask."""
    return ((np.asarray(masks)[:, None] >> np.arange(N_CANDIDATES)) & 1).astype(np.float64)


def candidate_centres(spec: SceneSpec = SceneSpec()) -> np.ndarray:
    """``(9, 3)`` centres of the candidate cylinders (candidate k ↔ bit k)."""
    k = np.arange(N_CANDIDATES)
    return np.stack([(k % 3 - 1) * spec.pitch, (k // 3 - 1) * spec.pitch, np.zeros(N_CANDIDATES)], axis=1)


def candidate_samples(spec: SceneSpec = SceneSpec()) -> tuple[np.ndarray, np.ndarray]:
    """``(samples (9·M, 3), owner (9·M,))``: M noise-free samples of each candidate."""
    clouds = [
        nine_cylinders(
            mask=1 << k, pitch=spec.pitch, radius=spec.radius, height=spec.height,
            points=spec.samples, jitter=0.0, drift=0.0, seed=k,
        )[0]
        for k in range(N_CANDIDATES)
    ]
    owner = np.repeat(np.arange(N_CANDIDATES), spec.samples)
    return np.concatenate(clouds), owner


class EmptyScene:
    """The loss of the empty scene (mask 0), duck-typed as a :class:`ChamferProblem`.

    With no cloud points the point term is 0 and every sample of an existing candidate
    is unexplained: ``g_i = M_i · cap``.
    """

    def __init__(self, samples_per_candidate: np.ndarray, cap: float, weights: tuple[float, float]) -> None:
        self.g = np.asarray(samples_per_candidate, dtype=np.float64) * cap
        self.weights = weights

    @property
    def n_candidates(self) -> int:
        """Number of candidates N."""
        return len(self.g)

    def evaluate(self, p: np.ndarray) -> tuple[float, float, np.ndarray]:
        """``(primitive_term, point_term, grad)`` as :meth:`ChamferProblem.evaluate`."""
        return float(self.g @ p), 0.0, self.weights[0] * self.g

    def evaluate_batch(self, P: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Weighted totals and gradients of rows ``P`` (B, N)."""
        return self.weights[0] * (P @ self.g), np.tile(self.weights[0] * self.g, (len(P), 1))


Problem = ChamferProblem | EmptyScene


@dataclass
class NineScenes:
    """A set of nine-cylinder scenes.

    Attributes
    ----------
    clouds : (S, J, 3) float32 array
        The points of every scene.
    masks : (S,) int array
        Which cylinders exist (bit k ↔ candidate k).
    problems : list of S problems, or None
        The chamfer loss of every scene (``None`` when not built).
    spec : SceneSpec
        How the scenes were made.
    """

    clouds: np.ndarray
    masks: np.ndarray
    problems: list[Problem] | None
    spec: SceneSpec

    def __len__(self) -> int:
        return len(self.masks)

    @property
    def labels(self) -> np.ndarray:
        """``(S, 9)`` true existences (0/1)."""
        return bits(self.masks)


def _cloud(mask: int, spec: SceneSpec, seed: int) -> np.ndarray:
    """The ``(points, 3)`` cloud of one scene (grid-centre copies for the empty scene)."""
    if mask == 0:
        return np.zeros((spec.points, 3))
    points, _ = nine_cylinders(
        mask=int(mask), pitch=spec.pitch, radius=spec.radius, height=spec.height, points=spec.points,
        jitter=spec.jitter, drift=spec.drift, offset=spec.offset, seed=seed,
    )
    return points


def _problems(clouds: Sequence[np.ndarray], masks: np.ndarray, spec: SceneSpec) -> list[Problem]:
    """One loss per scene: Rust problems built in one parallel call, plus empty scenes."""
    samples, owner = candidate_samples(spec)
    full = [b for b, m in enumerate(masks) if m != 0]
    built = chamfer_problems(
        [clouds[b] for b in full], samples, owner, N_CANDIDATES, cap=spec.cap, weights=spec.weights
    )
    problems: list[Problem] = [EmptyScene(np.bincount(owner), spec.cap, spec.weights)] * len(masks)
    for b, problem in zip(full, built):
        problems[b] = problem
    return problems


def make_scenes(
    masks: Sequence[int] | np.ndarray,
    *,
    copies: int = 1,
    spec: SceneSpec = SceneSpec(),
    seed: int = 0,
    problems: bool = True,
) -> NineScenes:
    """``copies`` scenes of every mask (different noise each), with their losses.

    Scene ``s`` (masks repeated ``copies`` times, mask-major) uses generator seed
    ``seed + s``, so the same arguments give the same scenes; use disjoint seed ranges for
    training and test sets.
    """
    masks = np.repeat(np.asarray(masks, dtype=np.int64), copies)
    clouds = np.stack([_cloud(int(m), spec, seed + s) for s, m in enumerate(masks)]).astype(np.float32)
    return NineScenes(
        clouds=clouds,
        masks=masks,
        # The loss sees exactly the (float32) points the network sees.
        problems=_problems(list(clouds), masks, spec) if problems else None,
        spec=spec,
    )


def with_offset(spec: SceneSpec, offset: float) -> SceneSpec:
    """``spec`` with another alignment offset."""
    return replace(spec, offset=offset)
