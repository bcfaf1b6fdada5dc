"""primfit.torch: the Rust loss and gradient as a torch autograd function.

These tests need torch; they skip without it, and fail under PRIMFIT_REQUIRE_ALL=1.
"""

from __future__ import annotations

import numpy as np
import pytest
from conftest import random_problem, require

import primfit


@pytest.fixture
def torch():
    return require("torch")


@pytest.fixture
def pt(torch):
    import primfit.torch as pt

    return pt


def make_problem(seed, model="existence", **kw):
    cloud, samples, owner, _ = random_problem(seed, j=25, n=6, per=4)
    return primfit.ChamferProblem(cloud, samples, owner, model=model, cap=0.3, weights=(0.8, 1.2), **kw)


@pytest.mark.parametrize("model", ["existence", "independent"])
def test_gradcheck_batched(torch, pt, model):
    problem = make_problem(0, model)
    p = torch.rand(3, problem.n_candidates, dtype=torch.float64) * 0.8 + 0.1
    p.requires_grad_(True)
    assert torch.autograd.gradcheck(lambda q: pt.ChamferLoss.apply(q, problem), (p,), eps=1e-6, atol=1e-7)


def test_gradcheck_single_row_through_sigmoid(torch, pt):
    problem = make_problem(1)
    logits = torch.randn(problem.n_candidates, dtype=torch.float64, requires_grad=True)
    assert torch.autograd.gradcheck(lambda z: pt.chamfer_loss(torch.sigmoid(z), problem), (logits,))


def test_batch_of_scenes(torch, pt):
    problems = [make_problem(s) for s in range(3)]
    p = torch.full((3, problems[0].n_candidates), 0.5, dtype=torch.float64, requires_grad=True)
    loss = pt.chamfer_loss(p, problems)
    assert loss.shape == (3,)
    loss.sum().backward()
    for b, problem in enumerate(problems):
        prim, point, grad = problem.evaluate(np.full(problem.n_candidates, 0.5))
        assert loss[b].item() == pytest.approx(0.8 * prim + 1.2 * point, rel=1e-13)
        np.testing.assert_allclose(p.grad[b].numpy(), grad, rtol=1e-13)
    assert torch.autograd.gradcheck(lambda q: pt.chamfer_loss(q, problems), (p.detach().clone().requires_grad_(),))
    with pytest.raises(ValueError, match="2 problems for a batch of 3"):
        pt.chamfer_loss(p, problems[:2])


def test_values_match_numpy_and_dtype_is_kept(torch, pt):
    problem = make_problem(2)
    P = np.random.default_rng(0).random((4, problem.n_candidates))
    totals, grads = problem.evaluate_batch(P)
    p32 = torch.tensor(P, dtype=torch.float32, requires_grad=True)
    loss = pt.chamfer_loss(p32, problem)
    assert loss.dtype == torch.float32 and loss.shape == (4,)
    (loss * torch.arange(1.0, 5.0)).sum().backward()
    assert p32.grad.dtype == torch.float32
    expected_totals, expected_grads = problem.evaluate_batch(P.astype(np.float32).astype(np.float64))
    np.testing.assert_allclose(loss.detach().numpy(), expected_totals, rtol=1e-6)
    np.testing.assert_allclose(p32.grad.numpy(), np.arange(1.0, 5.0)[:, None] * expected_grads, rtol=1e-5)
    scalar = pt.chamfer_loss(torch.tensor(P[0]), problem)
    assert scalar.shape == () and scalar.item() == pytest.approx(totals[0], rel=1e-14)


def test_training_step_lowers_the_loss(torch, pt):
    problem = make_problem(3)
    logits = torch.zeros(problem.n_candidates, dtype=torch.float64, requires_grad=True)
    opt = torch.optim.Adam([logits], lr=0.1)
    losses = []
    for _ in range(30):
        opt.zero_grad()
        loss = pt.chamfer_loss(torch.sigmoid(logits), problem)
        loss.backward()
        opt.step()
        losses.append(loss.item())
    assert losses[-1] < losses[0]


def test_bad_inputs(torch, pt):
    problem = make_problem(4)
    with pytest.raises(ValueError, match=r"shape \(N,\) or \(B, N\)"):
        pt.chamfer_loss(torch.zeros(2, 2, problem.n_candidates), problem)
    with pytest.raises(ValueError, match="not a probability"):
        pt.chamfer_loss(torch.full((1, problem.n_candidates), 2.0), problem)
