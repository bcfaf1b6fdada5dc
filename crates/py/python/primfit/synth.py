"""Synthetic scenes with ground truth (the core's ``synth`` generators).

Every function returns ``(points, truth)``: the sampled cloud as a (J, 3) float64 array
and the true primitives as a list of dicts in the ``result.json`` format (``type``,
``size``, ``pose``). Same parameters and seed give the same scene, bit for bit.

Noise: ``jitter`` is the σ of an independent per-point offset, ``drift`` the σ of one
offset per surface piece; ``offset`` (in lattice steps) and ``angle`` (radians) bound a
random rigid misalignment of cloud and truth. Point counts: ``density`` is points per
unit area, ``points`` a total (give at most one).
"""

from __future__ import annotations

import json
from typing import Any

import numpy as np
import numpy.typing as npt

from . import _primfit
from ._convert import _ints, _points

__all__ = ["hallway", "nine_cylinders", "partial_view", "pipe", "registration", "six_in_a_row"]

Truth = list[dict[str, Any]]


def _scene(out: tuple[np.ndarray, str]) -> tuple[np.ndarray, Truth]:
    points, truth = out
    return points, json.loads(truth)


def hallway(
    *,
    length: float = 10.0,
    width: float = 2.0,
    height: float = 2.5,
    side: float = 1.0,
    ceiling: bool = False,
    density: float | None = None,
    points: int | None = None,
    jitter: float = 0.01,
    drift: float = 0.0,
    offset: float = 0.0,
    angle: float = 0.0,
    seed: int = 0,
) -> tuple[np.ndarray, Truth]:
    """A hallway along x tiled with squares of ``side``: floor, two walls, optional ceiling.

    Tiles lie on a lattice of step ``side / 2`` with origin 0. Default density: 100
    points per unit area.
    """
    return _scene(
        _primfit.synth_hallway(
            length=length, width=width, height=height, side=side, ceiling=ceiling, density=density,
            points=points, jitter=jitter, drift=drift, offset=offset, angle=angle, seed=seed,
        )
    )


def pipe(
    *,
    segments: int = 4,
    max_run: int = 3,
    segment_length: float = 1.0,
    bend: float | None = None,
    radius: float | None = None,
    density: float | None = None,
    points: int | None = None,
    jitter: float = 0.005,
    drift: float = 0.0,
    offset: float = 0.0,
    angle: float = 0.0,
    seed: int = 0,
) -> tuple[np.ndarray, Truth]:
    """A pipe of ``segments`` straight runs (≤ ``max_run`` cylinders each) joined by elbows.

    ``bend`` defaults to ``segment_length / 2``, ``radius`` to ``0.1 * segment_length``.
    Default density: 1000 points per unit area.
    """
    return _scene(
        _primfit.synth_pipe(
            segments=segments, max_run=max_run, segment_length=segment_length, bend=bend, radius=radius,
            density=density, points=points, jitter=jitter, drift=drift, offset=offset, angle=angle, seed=seed,
        )
    )


def nine_cylinders(
    *,
    mask: int = 0b1_1111_1111,
    pitch: float = 1.0,
    radius: float = 0.2,
    height: float = 1.0,
    density: float | None = None,
    points: int | None = None,
    jitter: float = 0.01,
    drift: float = 0.01,
    offset: float = 0.0,
    seed: int = 0,
) -> tuple[np.ndarray, Truth]:
    """Vertical cylinders on a 3 × 3 grid of ``pitch``; bit k of ``mask`` keeps cylinder k.

    ``offset`` shifts the whole scene by up to that many pitches along ±x or ±y.
    Default density: 200 points per unit area.
    """
    return _scene(
        _primfit.synth_nine_cylinders(
            mask=mask, pitch=pitch, radius=radius, height=height, density=density, points=points,
            jitter=jitter, drift=drift, offset=offset, seed=seed,
        )
    )


def six_in_a_row(
    *,
    variant: str = "squares",
    first: float = 7.0,
    step: float = 1.0,
    true_index: int = 3,
    size: float = 1.0,
    points: int = 500,
    jitter: float = 0.01,
    seed: int = 0,
) -> tuple[np.ndarray, Truth]:
    """``points`` points seen from the origin on candidate ``true_index`` of six in a row.

    Candidates (``"squares"`` facing the sensor or vertical ``"cylinders"``) sit at
    ``(first + i * step, 0, 0)``; noise is along each ray (range).
    """
    return _scene(
        _primfit.synth_six_in_a_row(
            variant=variant, first=first, step=step, true_index=true_index, size=size, points=points,
            jitter=jitter, seed=seed,
        )
    )


def registration(
    *,
    mesh: tuple[npt.ArrayLike, npt.ArrayLike] | None = None,
    inliers: int = 100,
    outliers: int = 1900,
    translation: float = 0.0,
    scale: tuple[float, float] | None = None,
    outlier_box: float = 1.0,
    jitter: float = 0.0,
    seed: int = 0,
) -> tuple[np.ndarray, Truth]:
    """``inliers`` points on a randomly posed mesh, then ``outliers`` uniform points.

    ``mesh`` is ``(vertices (V, 3), faces (F, 3) int)``; default: a built-in asymmetric
    object. The cloud lists the inliers first; the truth is the one posed mesh.
    """
    m = None
    if mesh is not None:
        m = (_points("mesh vertices", mesh[0]), _ints("mesh faces", mesh[1], 2))
    return _scene(
        _primfit.synth_registration(
            mesh=m, inliers=inliers, outliers=outliers, translation=translation, scale=scale,
            outlier_box=outlier_box, jitter=jitter, seed=seed,
        )
    )


def partial_view(
    *,
    mesh: tuple[npt.ArrayLike, npt.ArrayLike] | None = None,
    inliers: int = 400,
    outliers: int = 3600,
    clutter_points: int = 0,
    plane: bool = False,
    distractors: int = 0,
    object: bool = True,
    translation: float = 0.0,
    range_noise: float = 0.0,
    outlier_box: float = 1.0,
    seed: int = 0,
) -> tuple[np.ndarray, Truth]:
    """A randomly posed mesh seen by a depth sensor from one random viewpoint.

    Only the object's near side is seen (self-occluded, ``range_noise`` along each ray);
    ``inliers`` of its pixels are kept, then ``clutter_points`` of the scan of a plane
    under it (``plane``) and ``distractors`` other objects, then ``outliers`` uniform
    points in a cube of half-side ``outlier_box`` bounding radii around it. ``object=False``
    leaves the object out (empty truth). ``mesh`` as in :func:`registration`.
    """
    m = None
    if mesh is not None:
        m = (_points("mesh vertices", mesh[0]), _ints("mesh faces", mesh[1], 2))
    return _scene(
        _primfit.synth_partial_view(
            mesh=m, inliers=inliers, outliers=outliers, clutter_points=clutter_points, plane=plane,
            distractors=distractors, object=object, translation=translation, range_noise=range_noise,
            outlier_box=outlier_box, seed=seed,
        )
    )
