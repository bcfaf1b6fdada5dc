"""Synthetic scenes from Python, and fitting them."""

from __future__ import annotations

import numpy as np
import pytest

import primfit
from primfit import synth


def test_scenes_are_deterministic_and_have_truth():
    for make in (synth.hallway, synth.pipe, synth.nine_cylinders, synth.six_in_a_row, synth.registration):
        points, truth = make(seed=3)
        again, truth2 = make(seed=3)
        other, _ = make(seed=4)
        assert points.dtype == np.float64 and points.ndim == 2 and points.shape[1] == 3 and len(points) > 0
        np.testing.assert_array_equal(points, again)
        assert truth == truth2 and truth
        assert not np.array_equal(points, other)
        for q in truth:
            assert {"type", "size", "pose"} <= set(q)


def test_scene_parameters():
    points, truth = synth.hallway(length=4.0, points=1000, jitter=0.0, ceiling=True)
    assert len(points) == 1000
    assert {q["type"] for q in truth} == {"square"}
    points, truth = synth.nine_cylinders(mask=0b101, points=500)
    assert len(truth) == 2 and {q["type"] for q in truth} == {"cylinder"}
    _, truth = synth.six_in_a_row(variant="cylinders")
    assert [q["type"] for q in truth] == ["cylinder"]
    v = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], dtype=float)
    f = np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]])
    points, truth = synth.registration(mesh=(v, f), inliers=50, outliers=10)
    assert len(points) == 60 and truth[0]["type"] == "mesh"


def test_partial_view_scene():
    points, truth = synth.partial_view(inliers=200, outliers=300, clutter_points=100, plane=True,
                                       distractors=2, seed=2)
    again, _ = synth.partial_view(inliers=200, outliers=300, clutter_points=100, plane=True,
                                  distractors=2, seed=2)
    np.testing.assert_array_equal(points, again)
    assert len(points) == 600 and len(truth) == 1 and truth[0]["type"] == "mesh"
    empty, none = synth.partial_view(inliers=200, outliers=300, object=False, seed=2)
    assert len(empty) == 300 and none == []
    with pytest.raises(ValueError):
        synth.partial_view(range_noise=-1.0)


def test_bad_scene_parameters():
    with pytest.raises(ValueError, match="not both"):
        synth.hallway(density=10.0, points=100)
    with pytest.raises(ValueError):
        synth.six_in_a_row(true_index=9)
    with pytest.raises(ValueError, match="variant"):
        synth.six_in_a_row(variant="spheres")
    with pytest.raises(ValueError):
        synth.nine_cylinders(pitch=-1.0)


def test_fit_explains_a_noise_free_hallway_with_tiles_on_its_surfaces():
    points, truth = synth.hallway(length=4.0, width=2.0, height=2.0, jitter=0.0, density=200.0, seed=1)
    # The plain lattice pipeline (squares, scene axes, no refinement): exactly on the lattice.
    result = primfit.fit(points, types="square", size=1.0, spacing=0.5, frame="axis", refine=False)
    assert result.metrics["point_to_model_max"] < 1e-9  # every point on a fitted square
    assert result.metrics["coverage"] == 1.0
    assert len(truth) <= len(result) <= len(truth) + 2
    # Every fitted square lies in the floor (z = 0) or a wall (y = 0 or y = 2).
    for q in result.primitives:
        x, y, z = q["pose"]["translation"]
        assert min(abs(z), abs(y), abs(y - 2.0)) < 1e-9, q
