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

    For candidate i with centre c_i and frame R_i (columns: its axes in scene
    coordinates): up to ``k`` cloud points within ``radius`` of c_i, expressed in its
    frame as ``R_iᵀ (y - c_i) / scale``; a shared per-point MLP, a max-pool over the
    kept points, an "empty neighbourhood" flag, the candidate's type (one-hot, when
    ``n_types > 1``), and an MLP to one logit; the scaled tanh gives the existence.
    Moving the scene and the candidates together (rotation and translation) leaves it
    unchanged. The candidate set is fixed at construction and can be replaced with
    :meth:`set_candidates`.

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
    n_types : int
        Number of candidate types (e.g. 2: cylinder, elbow).
    rotations : (N, 3, 3) array-like, optional
        Candidate frames (default: the scene's axes).
    types : (N,) int array-like, optional
        Candidate types in ``0..n_types`` (default 0).
    """

    #: Candidate centres (N, 3), frames (N, 3, 3) and types (N,): buffers (they move with
    #: the module's device and are saved with the weights).
    centres: Tensor
    rotations: Tensor
    types: Tensor

    def __init__(
        self,
        centres: Tensor | npt.ArrayLike,
        *,
        radius: float = 0.7,
        scale: float = 1.0,
        k: int = 32,
        width: float = 1.0,
        n_types: int = 1,
        rotations: Tensor | npt.ArrayLike | None = None,
        types: Tensor | npt.ArrayLike | None = None,
    ) -> None:
        super().__init__()
        w = lambda c: max(4, int(round(c * width)))  # noqa: E731
        self.radius, self.scale, self.k, self.n_types = radius, scale, k, n_types
        self.register_buffer("centres", torch.zeros(0, 3))
        self.register_buffer("rotations", torch.zeros(0, 3, 3))
        self.register_buffer("types", torch.zeros(0, dtype=torch.long))
        self.set_candidates(centres, rotations, types)
        #: The constructor's arguments but the candidates (buffers, saved with the weights).
        self.hparams = {"radius": radius, "scale": scale, "k": k, "width": width, "n_types": n_types}
        self.point_mlp = _mlp([3, w(32), w(64), w(128)])
        type_features = n_types if n_types > 1 else 0
        self.head = nn.Sequential(_mlp([w(128) + 1 + type_features, w(64)]), nn.Linear(w(64), 1))

    def set_candidates(
        self,
        centres: Tensor | npt.ArrayLike,
        rotations: Tensor | npt.ArrayLike | None = None,
        types: Tensor | npt.ArrayLike | None = None,
    ) -> None:
        """Replaces the candidates (any number N; the weights are shared)."""
        device = self.centres.device
        c = torch.as_tensor(centres, dtype=torch.float32, device=device).reshape(-1, 3)
        n = c.shape[0]
        r = torch.eye(3, device=device).expand(n, 3, 3) if rotations is None else rotations
        t = torch.zeros(n, dtype=torch.long) if types is None else types
        self.centres = c
        self.rotations = torch.as_tensor(r, dtype=torch.float32, device=device).reshape(n, 3, 3).contiguous()
        self.types = torch.as_tensor(t, dtype=torch.long, device=device).reshape(n)
        if n and not 0 <= int(self.types.min()) <= int(self.types.max()) < self.n_types:
            raise ValueError(f"candidate types must be in 0..{self.n_types}")

    def neighbourhoods(self, xyz: Tensor, *, chunk: int = 512) -> tuple[Tensor, Tensor]:
        """Local points ``(B, N, k, 3)`` and validity ``(B, N, k)`` of every candidate: the
        first ``k`` points (by index, as a ball query) within ``radius`` of its centre, in
        its frame. Candidates go ``chunk`` at a time (memory ``B · chunk · J``).

        Taking them by index rather than by distance keeps a uniform subset of a dense
        neighbourhood (the nearest ones would be a band around the centre).
        """
        parts = [
            self._neighbourhoods(xyz, self.centres[s : s + chunk], self.rotations[s : s + chunk])
            for s in range(0, self.centres.shape[0], chunk)
        ]
        if not parts:
            b = xyz.shape[0]
            return xyz.new_zeros(b, 0, self.k, 3), torch.zeros(b, 0, self.k, dtype=torch.bool, device=xyz.device)
        return torch.cat([p[0] for p in parts], dim=1), torch.cat([p[1] for p in parts], dim=1)

    def _neighbourhoods(self, xyz: Tensor, centres: Tensor, rotations: Tensor) -> tuple[Tensor, Tensor]:
        b, j, _ = xyz.shape
        n = centres.shape[0]
        centres = centres.to(xyz.dtype).expand(b, n, 3)
        inside = square_distance(centres, xyz) <= self.radius**2  # (B, n, J)
        order = torch.arange(j, device=xyz.device).expand(b, n, j)
        key = torch.where(inside, order, order + j)
        idx = key.topk(min(self.k, j), dim=-1, largest=False).values
        valid = idx < j
        idx = torch.where(valid, idx, idx - j)
        # Row vectors: (y − c) R = (Rᵀ (y − c))ᵀ, the offset in the candidate's frame.
        offsets = gather_points(xyz, idx) - centres[:, :, None, :]
        local = torch.einsum("bnkc,ncd->bnkd", offsets, rotations.to(xyz.dtype)) / self.scale
        return local, valid

    def logits_of(self, local: Tensor, valid: Tensor) -> Tensor:
        """Pre-activations ``(B, N)`` from :meth:`neighbourhoods` (which need no weights:
        compute them once to train on a fixed set of scenes)."""
        f = self.point_mlp(local) * valid[..., None]  # ReLU features ≥ 0: masked max = max
        pooled = f.max(dim=2).values
        features = [pooled, (~valid.any(dim=-1)).to(pooled.dtype)[..., None]]
        if self.n_types > 1:
            one_hot = nn.functional.one_hot(self.types, self.n_types).to(pooled.dtype)
            features.append(one_hot.expand(pooled.shape[0], -1, -1))
        return self.head(torch.cat(features, dim=-1))[..., 0]

    def logits(self, xyz: Tensor) -> Tensor:
        """Clouds ``(B, J, 3)`` → pre-activations ``z`` ``(B, N)``; existence is
        ``scaled_tanh(z)``."""
        return self.logits_of(*self.neighbourhoods(xyz))

    def forward(self, xyz: Tensor) -> Tensor:
        """Clouds ``(B, J, 3)`` → existences ``(B, N)`` in [0, 1]."""
        return scaled_tanh(self.logits(xyz))


#: Either existence network (both have ``logits`` and ``hparams``).
ExistenceNetwork = PointNet2 | LocalExistence
