"""PyTorch integration: the probabilistic chamfer distance as an autograd function.

Import it explicitly (``import primfit.torch``); torch is an optional dependency.

The forward pass computes the loss and its exact gradient in Rust (GIL released,
batch rows in parallel) and saves the gradient; the backward pass only scales it, so
no graph is built through the loss. Computation is in float64 whatever the input
dtype; results are cast back to the input's dtype and device.

Example::

    import torch, primfit, primfit.torch as pt
    problem = primfit.ChamferProblem(cloud, samples, owner, cap=0.25)
    logits = torch.zeros(4, problem.n_candidates, requires_grad=True)
    loss = pt.chamfer_loss(torch.sigmoid(logits), problem).sum()
    loss.backward()
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import torch
from torch.autograd.function import once_differentiable

from . import ChamferProblem

__all__ = ["ChamferLoss", "chamfer_loss"]

Problems = ChamferProblem | Sequence[ChamferProblem]


def _evaluate(p: np.ndarray, problem: Problems) -> tuple[np.ndarray, np.ndarray]:
    """Totals (B,) and gradients (B, N) of rows ``p`` (B, N)."""
    if isinstance(problem, ChamferProblem):
        return problem.evaluate_batch(p)
    if len(problem) != len(p):
        raise ValueError(f"{len(problem)} problems for a batch of {len(p)} rows")
    totals = np.empty(len(p))
    grads = np.empty_like(p)
    for b, (row, prob) in enumerate(zip(p, problem)):
        totals[b], grads[b] = _weighted(prob, row)
    return totals, grads


def _weighted(problem: ChamferProblem, p: np.ndarray) -> tuple[float, np.ndarray]:
    prim, point, grad = problem.evaluate(p)
    w_prim, w_point = problem.weights
    return w_prim * prim + w_point * point, grad


class ChamferLoss(torch.autograd.Function):
    """``ChamferLoss.apply(p, problem)``: weighted probabilistic chamfer loss.

    ``p`` holds existence probabilities in [0, 1], shape (N,) or (B, N). ``problem`` is
    one :class:`primfit.ChamferProblem` (every row is evaluated against it, rows in
    parallel) or a sequence of B problems with N candidates each (row b against problem
    b: a batch of scenes). Returns a scalar for (N,) input, (B,) losses otherwise.
    """

    @staticmethod
    def forward(ctx, p: torch.Tensor, problem: Problems) -> torch.Tensor:  # type: ignore[override]
        if p.dim() not in (1, 2):
            raise ValueError(f"p must have shape (N,) or (B, N), got {tuple(p.shape)}")
        rows = p.detach().to("cpu", torch.float64).reshape(-1, p.shape[-1]).numpy()
        if p.dim() == 1 and not isinstance(problem, ChamferProblem):
            raise ValueError("a single row p (N,) needs a single ChamferProblem")
        totals, grads = _evaluate(np.ascontiguousarray(rows), problem)
        ctx.save_for_backward(torch.from_numpy(grads).reshape(p.shape).to(device=p.device, dtype=p.dtype))
        out = torch.from_numpy(totals).to(device=p.device, dtype=p.dtype)
        return out.reshape(()) if p.dim() == 1 else out

    @staticmethod
    @once_differentiable
    def backward(ctx, grad_out: torch.Tensor) -> tuple[torch.Tensor, None]:  # type: ignore[override]
        (grad,) = ctx.saved_tensors
        scale = grad_out if grad.dim() == 1 else grad_out.unsqueeze(-1)
        return scale * grad, None


def chamfer_loss(p: torch.Tensor, problem: Problems) -> torch.Tensor:
    """The weighted probabilistic chamfer loss of ``p`` (N,) or (B, N); see :class:`ChamferLoss`."""
    return ChamferLoss.apply(p, problem)
