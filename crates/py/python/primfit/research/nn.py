"""Existence networks for a fixed candidate set, in plain PyTorch (no custom CUDA ops).

Two architectures map a cloud ``(B, J, 3)`` to one existence value in [0, 1] per
candidate, ``(B, N)``:

* :class:`PointNet2` — the thesis's network (§5.4): three PointNet++ set-abstraction
  layers (farthest point sampling, ball-query grouping, shared MLP + max-pool; the last
  one groups everything), two fully connected + batch-norm + ReLU + dropout layers, and
  a fully connected layer with a scaled tanh ``(1 + tanh z) / 2``. With
  ``head="logits"`` it is the supervised baseline instead: raw logits over the 2^N
  subsets (cross-entropy).
* :class:`LocalExistence` — beyond the thesis: the same small PointNet, with shared
  weights, applied to every candidate's neighbourhood (the points within ``radius`` of
  its centre, in its local frame). Translating scene and candidates together leaves the
  output unchanged, and what it learns about one candidate applies to every other one.

Both run on any device; the helpers (:func:`farthest_point_sample`, :func:`ball_query`)
are deterministic.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy.typing as npt
import torch
from torch import Tensor, nn

__all__ = [
    "ExistenceNetwork",
    "LocalExistence",
    "PointNet2",
    "SetAbstraction",
    "SharedMLP",
    "ball_query",
    "farthest_point_sample",
    "gather_points",
    "scaled_tanh",
    "square_distance",
]


def scaled_tanh(z: Tensor) -> Tensor:
    """``(1 + tanh z) / 2``: a value in [0, 1] per entry (the thesis's output activation)."""
    return 0.5 * (1.0 + torch.tanh(z))


def square_distance(a: Tensor, b: Tensor) -> Tensor:
    """Squared distances ``(B, S, J)`` between points ``a`` (B, S, 3) and ``b`` (B, J, 3)."""
    return ((a[:, :, None, :] - b[:, None, :, :]) ** 2).sum(-1)


def gather_points(points: Tensor, idx: Tensor) -> Tensor:
    """``points`` (B, J, C) at indices ``idx`` (B, ...) → (B, ..., C)."""
    b = points.shape[0]
    flat = idx.reshape(b, -1)
    out = torch.gather(points, 1, flat[..., None].expand(-1, -1, points.shape[-1]))
    return out.reshape(*idx.shape, points.shape[-1])


@torch.no_grad()
def farthest_point_sample(xyz: Tensor, n: int) -> Tensor:
    """Indices ``(B, n)`` of ``n`` points chosen by farthest point sampling.

    Starts from point 0; each next point maximises the distance to those chosen (ties:
    lowest index). Deterministic.
    """
    b, j, _ = xyz.shape
    if not 1 <= n <= j:
        raise ValueError(f"cannot sample {n} of {j} points")
    chosen = torch.zeros(b, n, dtype=torch.long, device=xyz.device)
    nearest = torch.full((b, j), float("inf"), dtype=xyz.dtype, device=xyz.device)
    current = torch.zeros(b, dtype=torch.long, device=xyz.device)
    rows = torch.arange(b, device=xyz.device)
    for i in range(n):
        chosen[:, i] = current
        d = ((xyz - xyz[rows, current][:, None, :]) ** 2).sum(-1)
        nearest = torch.minimum(nearest, d)
        current = nearest.argmax(-1)
    return chosen


@torch.no_grad()
def ball_query(xyz: Tensor, centres: Tensor, radius: float, k: int) -> Tensor:
    """Indices ``(B, S, k)``: for every centre, the first ``k`` points (by index) within
    ``radius``, padded with the first one found (as PointNet++ does).

    Every centre must have a point within ``radius`` (true when centres are cloud points).
    """
    b, j, _ = xyz.shape
    d2 = square_distance(centres, xyz)
    idx = torch.arange(j, device=xyz.device).expand(b, centres.shape[1], j).clone()
    idx[d2 > radius * radius] = j
    idx = idx.sort(dim=-1).values[..., :k]
    if idx.shape[-1] < k:
        idx = torch.cat([idx, idx.new_full((*idx.shape[:-1], k - idx.shape[-1]), j)], dim=-1)
    first = idx[..., :1].expand_as(idx)
    return torch.where(idx == j, first, idx)


class SharedMLP(nn.Module):
    """Linear + batch norm + ReLU layers applied to every point of ``(..., C)`` alike
    (PointNet's shared MLP; channels-last matrix products, fast on CPU)."""

    def __init__(self, channels: Sequence[int]) -> None:
        super().__init__()
        layers: list[nn.Module] = []
        for c_in, c_out in zip(channels[:-1], channels[1:]):
            layers += [nn.Linear(c_in, c_out, bias=False), nn.BatchNorm1d(c_out), nn.ReLU()]
        self.layers = nn.Sequential(*layers)

    def forward(self, x: Tensor) -> Tensor:
        """``(..., C)`` → ``(..., C')``."""
        return self.layers(x.reshape(-1, x.shape[-1])).reshape(*x.shape[:-1], -1)


class SetAbstraction(nn.Module):
    """A PointNet++ set-abstraction layer: sample, group, shared MLP, max-pool.

    ``n_centres=None`` groups all points around the origin (the final layer).
    """

    def __init__(
        self, n_centres: int | None, radius: float, k: int, in_features: int, mlp: Sequence[int]
    ) -> None:
        super().__init__()
        self.n_centres, self.radius, self.k = n_centres, radius, k
        self.mlp = SharedMLP([in_features + 3, *mlp])
        self.out_features = mlp[-1]

    def forward(self, xyz: Tensor, features: Tensor | None) -> tuple[Tensor, Tensor]:
        """``(xyz (B, J, 3), features (B, J, C) or None)`` → ``(centres (B, S, 3), (B, S, C'))``."""
        if self.n_centres is None:
            centres = xyz.new_zeros(xyz.shape[0], 1, 3)
            grouped = xyz[:, None]
            feats = None if features is None else features[:, None]
        else:
            centres = gather_points(xyz, farthest_point_sample(xyz, self.n_centres))
            idx = ball_query(xyz, centres, self.radius, self.k)
            grouped = gather_points(xyz, idx) - centres[:, :, None, :]
            feats = None if features is None else gather_points(features, idx)
        x = grouped if feats is None else torch.cat([grouped, feats], dim=-1)
        return centres, self.mlp(x).max(dim=2).values


def _fc_block(c_in: int, c_out: int, dropout: float) -> list[nn.Module]:
    return [nn.Linear(c_in, c_out, bias=False), nn.BatchNorm1d(c_out), nn.ReLU(), nn.Dropout(dropout)]


class PointNet2(nn.Module):
    """The thesis's existence network (§5.4): 3 set abstractions, 2 FC blocks, a head.

    Parameters
    ----------
    n_out : int
        Candidates N (``head="existence"``) or classes (``head="logits"``).
    head : {"existence", "logits"}
        Scaled tanh to [0, 1] per output, or raw logits (the cross-entropy baseline).
    width : float
        Multiplier of every layer's width (1.0: 64-128-256 features, FC 128-64, as
        PointNet++'s classifier at half width; the default 0.5 trains in minutes on a CPU).
    centres : (int, int)
        Points sampled by the first two set abstractions (default sized for ~256-point
        clouds).
    radii : (float, float)
        Their ball-query radii (scene units).
    k : int
        Points per ball.
    dropout : float
        Dropout rate of the FC blocks (default 0: with FC blocks this narrow, dropout
        left one output blind to its cylinder in two of three seeds, see
        ``docs/nn_results.md``).
    """

    def __init__(
        self,
        n_out: int,
        *,
        head: str = "existence",
        width: float = 0.5,
        centres: tuple[int, int] = (32, 8),
        radii: tuple[float, float] = (0.3, 0.8),
        k: int = 16,
        dropout: float = 0.0,
    ) -> None:
        super().__init__()
        if head not in ("existence", "logits"):
            raise ValueError(f"head must be 'existence' or 'logits', got {head!r}")
        w = lambda c: max(4, int(round(c * width)))  # noqa: E731
        #: The constructor's arguments (plain data: rebuilds the network, see
        #: :mod:`primfit.research.pretrained`).
        self.hparams = {
            "n_out": n_out, "head": head, "width": width, "centres": list(centres), "radii": list(radii),
            "k": k, "dropout": dropout,
        }
        self.head = head
        self.sa1 = SetAbstraction(centres[0], radii[0], k, 0, [w(32), w(32), w(64)])
        self.sa2 = SetAbstraction(centres[1], radii[1], k, w(64), [w(64), w(64), w(128)])
        self.sa3 = SetAbstraction(None, 0.0, 0, w(128), [w(128), w(256)])
        self.fc = nn.Sequential(*_fc_block(w(256), w(128), dropout), *_fc_block(w(128), w(64), dropout))
        self.out = nn.Linear(w(64), n_out)

    def logits(self, xyz: Tensor) -> Tensor:
        """Clouds ``(B, J, 3)`` → pre-activations ``z`` ``(B, N)``: existence is
        ``scaled_tanh(z)`` (or, with ``head="logits"``, the class logits)."""
        xyz, f = self.sa1(xyz, None)
        xyz, f = self.sa2(xyz, f)
        _, f = self.sa3(xyz, f)
        return self.out(self.fc(f[:, 0]))

    def forward(self, xyz: Tensor) -> Tensor:
        """Clouds ``(B, J, 3)`` → existences ``(B, N)`` in [0, 1] (or logits)."""
        z = self.logits(xyz)
        return scaled_tanh(z) if self.head == "existence" else z


def _mlp(channels: Sequence[int]) -> nn.Sequential:
    """Linear + ReLU layers over the last dimension."""
    layers: list[nn.Module] = []
    for c_in, c_out in zip(channels[:-1], channels[1:]):
        layers += [nn.Linear(c_in, c_out), nn.ReLU()]
    return nn.Sequential(*layers)


class LocalExistence(nn.Module):
    """Per-candidate existence from the points around each candidate (shared weights).

    For candidate i with centre c_i: up to ``k`` cloud points within ``radius`` of c_i,
    expressed as ``(y - c_i) / scale``; a shared per-point MLP, a
    max-pool over the kept points, an "empty neighbourhood" flag, and an MLP to one
    logit; the scaled tanh gives the existence. The candidate set is fixed at
    construction (``centres``) and can be replaced with :meth:`set_candidates`.

    Parameters
    ----------
    centres : (N, 3) array-like
        Candidate centres (scene units).
    radius : float
        Neighbourhood radius (scene units).
    scale : float
        Local coordinates are divided by it (e.g. the lattice pitch).
    k : int
        At most this many points per neighbourhood.
    width : float
        Multiplier of the layer widths (1.0: point MLP 32-64-128, head 64).
    """

    #: Candidate centres (N, 3), a buffer (moves with the module's device).
    centres: Tensor

    def __init__(
        self,
        centres: Tensor | npt.ArrayLike,
        *,
        radius: float = 0.7,
        scale: float = 1.0,
        k: int = 32,
        width: float = 1.0,
    ) -> None:
        super().__init__()
        w = lambda c: max(4, int(round(c * width)))  # noqa: E731
        self.radius, self.scale, self.k = radius, scale, k
        self.register_buffer("centres", torch.as_tensor(centres, dtype=torch.float32).reshape(-1, 3))
        #: The constructor's arguments but the centres (a buffer, saved with the weights).
        self.hparams = {"radius": radius, "scale": scale, "k": k, "width": width}
        self.point_mlp = _mlp([3, w(32), w(64), w(128)])
        self.head = nn.Sequential(_mlp([w(128) + 1, w(64)]), nn.Linear(w(64), 1))

    def set_candidates(self, centres: Tensor | npt.ArrayLike) -> None:
        """Replaces the candidate centres (any number N; the weights are shared)."""
        self.centres = torch.as_tensor(centres, dtype=torch.float32, device=self.centres.device).reshape(-1, 3)

    def neighbourhoods(self, xyz: Tensor) -> tuple[Tensor, Tensor]:
        """Local points ``(B, N, k, 3)`` and validity ``(B, N, k)`` of every candidate: the
        first ``k`` points (by index, as a ball query) within ``radius`` of its centre.

        Taking them by index rather than by distance keeps a uniform subset of a dense
        neighbourhood (the nearest ones would be a band around the centre).
        """
        b, j, _ = xyz.shape
        n = self.centres.shape[0]
        centres = self.centres.to(xyz.dtype).expand(b, n, 3)
        inside = square_distance(centres, xyz) <= self.radius**2  # (B, N, J)
        order = torch.arange(j, device=xyz.device).expand(b, n, j)
        key = torch.where(inside, order, order + j)
        idx = key.topk(min(self.k, j), dim=-1, largest=False).values
        valid = idx < j
        idx = torch.where(valid, idx, idx - j)
        local = (gather_points(xyz, idx) - centres[:, :, None, :]) / self.scale
        return local, valid

    def logits(self, xyz: Tensor) -> Tensor:
        """Clouds ``(B, J, 3)`` → pre-activations ``z`` ``(B, N)``; existence is
        ``scaled_tanh(z)``."""
        local, valid = self.neighbourhoods(xyz)
        f = self.point_mlp(local) * valid[..., None]  # ReLU features ≥ 0: masked max = max
        pooled = f.max(dim=2).values
        empty = (~valid.any(dim=-1)).to(pooled.dtype)[..., None]
        return self.head(torch.cat([pooled, empty], dim=-1))[..., 0]

    def forward(self, xyz: Tensor) -> Tensor:
        """Clouds ``(B, J, 3)`` → existences ``(B, N)`` in [0, 1]."""
        return scaled_tanh(self.logits(xyz))


#: Either existence network (both have ``logits`` and ``hparams``).
ExistenceNetwork = PointNet2 | LocalExistence
