"""primfit.research.warm_start: a network's existence as the solver's start.

These tests need torch; they skip without it, and fail under PRIMFIT_REQUIRE_ALL=1.
"""

from __future__ import annotations

import numpy as np
import pytest
from conftest import require

import primfit


@pytest.fixture(scope="module")
def ws():
    require("torch").set_num_threads(1)
    import primfit.research.warm_start as ws

    return ws


def test_quaternion_rotation_matches_known_turns(ws):
    np.testing.assert_allclose(ws._rotation([1, 0, 0, 0]), np.eye(3), atol=1e-12)
    s = np.sqrt(0.5)  # 90° about z: x → y
    np.testing.assert_allclose(ws._rotation([s, 0, 0, s]) @ [1, 0, 0], [0, 1, 0], atol=1e-12)
    r = ws._rotation([0.5, 0.5, 0.5, 0.5])  # 120° about (1,1,1): x → y → z
    np.testing.assert_allclose(r @ [1, 0, 0], [0, 1, 0], atol=1e-12)
    np.testing.assert_allclose(r.T @ r, np.eye(3), atol=1e-12)


@pytest.fixture(scope="module")
def small_pipes(ws):
    return [ws.pipe_scene(primfit.synth.pipe(segments=2, seed=s)[0]) for s in (21, 22)]


def test_pipe_scene_describes_every_candidate(ws, small_pipes):
    s = small_pipes[0]
    n = s.problem.n_candidates
    assert s.centres.shape == (n, 3) and s.rotations.shape == (n, 3, 3) and s.types.shape == (n,)
    assert set(np.unique(s.types)) <= {0, 1} and np.isfinite(s.centres).all()
    np.testing.assert_allclose(np.einsum("nij,nik->njk", s.rotations, s.rotations), np.broadcast_to(np.eye(3), (n, 3, 3)), atol=1e-9)


def test_pipe_network_learns_the_solvers_decision_and_the_study_counts_both_solves(ws, small_pipes):
    model = ws.train_pipe_network(small_pipes, epochs=15)
    cost = ws.pipe_study(model, small_pipes)
    assert cost.problems == 2 and cost.network_seconds > 0
    assert cost.cold_iterations > 0 and cost.same_answer == 1.0 and cost.warm_loss_ratio == pytest.approx(1.0)
    # On its training scenes the network's existence, thresholded, is the solver's decision.
    import torch

    for s in small_pipes:
        with torch.no_grad():
            p = ws.scaled_tanh(model.logits_of(*ws._inputs(model, s)))[0].numpy()
        assert ((p > 0.5) == s.problem.solve(0.5).exists).mean() > 0.99


def test_nine_cylinder_warm_start_saves_iterations(ws):
    cost = ws.nine_cylinder_study("local", scenes=30, seed=4)
    assert cost.same_answer == 1.0
    assert cost.warm_iterations < 0.5 * cost.cold_iterations
