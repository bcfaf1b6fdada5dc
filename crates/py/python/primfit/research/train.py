"""Training and scoring of the existence networks on the nine-cylinder scenes (thesis §5.5).

Losses: ``chamfer`` (self-supervised: the probabilistic chamfer distance of each
scene, computed in Rust through :class:`primfit.torch.ChamferLoss`), ``ce`` (supervised
baseline of the thesis: cross-entropy over the 512 subsets, :class:`~primfit.research.nn.PointNet2`
only). Optimiser: Adam. Runs on CPU; uses CUDA when ``torch.cuda.is_available()``.

Command line (one training run, then scores on a test set)::

    python -m primfit.research.train --train all --test all --loss chamfer --arch local --epochs 40

Scores: *scene* accuracy (every one of the nine existences right), *primitive* accuracy
(share of the nine per-scene decisions right), and, of the true cylinders, the share
found (*recall*); of the absent ones, the share wrongly reported (*false positives*).
"""

from __future__ import annotations

import argparse
import math
import time
from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass

import numpy as np
import torch
from torch import Tensor, nn

from . import nine
from .nine import N_CANDIDATES, N_SUBSETS, NineScenes, SceneSpec
from .nn import ExistenceNetwork, LocalExistence, PointNet2, scaled_tanh
from ..torch import chamfer_loss

__all__ = [
    "ARCHS",
    "DEFAULT_LR",
    "DEFAULT_WIDTH",
    "LOGIT_PENALTY",
    "LOSSES",
    "SPLITS",
    "Scores",
    "TrainConfig",
    "build_model",
    "default_device",
    "main",
    "predict",
    "score",
    "split_masks",
    "train",
]

ARCHS = ("local", "pointnet2")
#: Width multiplier per architecture (sized for a 2-core CPU, see the README).
DEFAULT_WIDTH = {"local": 1.0, "pointnet2": 0.5}
#: Adam step per architecture (the thesis gives none; these train fastest in 40 epochs).
DEFAULT_LR = {"local": 3e-3, "pointnet2": 1e-2}
#: Weight λ of the logit penalty ``λ · mean(z²)`` added to the chamfer loss, where
#: ``p = (1 + tanh z) / 2`` (no effect on the cross-entropy baseline). Without it, an
#: output pushed far into the tanh's flat tail early in training gets a gradient of
#: ~1e-6 and stays wrong: two of PointNet++'s nine outputs stuck at 1 (z ≈ 7) was the
#: whole gap to the thesis (docs/nn_results.md, "Why PointNet++ fell short").
LOGIT_PENALTY = 3e-2
LOSSES = ("chamfer", "ce")
SPLITS: dict[str, Callable[[], np.ndarray]] = {
    "all": nine.all_masks,
    "multi": nine.multi_masks,
    "single": nine.single_masks,
    "pairs": nine.pair_masks,
}


@dataclass(frozen=True)
class TrainConfig:
    """One training run.

    Attributes
    ----------
    arch : {"local", "pointnet2"}
        :class:`~primfit.research.nn.LocalExistence` (default: it generalises, see the README) or
        the thesis's :class:`~primfit.research.nn.PointNet2`.
    loss : {"chamfer", "ce"}
        Self-supervised probabilistic chamfer, or the 512-class cross-entropy baseline.
    epochs, batch_size : int
        Adam for ``epochs`` passes over the training scenes in batches.
    lr : float or None
        Adam's step (``None``: :data:`DEFAULT_LR` of the architecture).
    width : float or None
        Layer-width multiplier of the network (``None``: :data:`DEFAULT_WIDTH`).
    seed : int
        Seed of the weights and the batch order.
    logit_penalty : float
        λ of the penalty ``λ · mean(z²)`` on the pre-activations (chamfer loss only;
        default :data:`LOGIT_PENALTY`).
    """

    arch: str = "local"
    loss: str = "chamfer"
    epochs: int = 40
    batch_size: int = 32
    lr: float | None = None
    width: float | None = None
    seed: int = 0
    logit_penalty: float = LOGIT_PENALTY

    def __post_init__(self) -> None:
        if self.arch not in ARCHS:
            raise ValueError(f"arch must be one of {ARCHS}, got {self.arch!r}")
        if self.loss not in LOSSES:
            raise ValueError(f"loss must be one of {LOSSES}, got {self.loss!r}")
        if self.loss == "ce" and self.arch != "pointnet2":
            raise ValueError("the cross-entropy baseline classifies subsets: arch must be 'pointnet2'")
        if not self.logit_penalty >= 0:
            raise ValueError(f"logit_penalty must be >= 0, got {self.logit_penalty!r}")

    @property
    def learning_rate(self) -> float:
        """Adam's step (the default resolved)."""
        return DEFAULT_LR[self.arch] if self.lr is None else self.lr

    @property
    def layer_width(self) -> float:
        """The width multiplier (the default resolved)."""
        return DEFAULT_WIDTH[self.arch] if self.width is None else self.width


@dataclass(frozen=True)
class Scores:
    """Accuracies of thresholded existences against the truth (see the module docstring)."""

    scene: float
    primitive: float
    recall: float
    false_positive: float


def default_device() -> torch.device:
    """CUDA when available, else CPU."""
    return torch.device("cuda" if torch.cuda.is_available() else "cpu")


def split_masks(name: str) -> np.ndarray:
    """The masks of a named split: ``all``, ``multi`` (≥ 2 cylinders), ``single``, ``pairs``."""
    try:
        return SPLITS[name]()
    except KeyError:
        raise ValueError(f"split must be one of {sorted(SPLITS)}, got {name!r}") from None


def build_model(config: TrainConfig, spec: SceneSpec = SceneSpec()) -> ExistenceNetwork:
    """The network of ``config``, seeded with ``config.seed``."""
    torch.manual_seed(config.seed)
    if config.arch == "local":
        return LocalExistence(
            nine.candidate_centres(spec), radius=0.7 * spec.pitch, scale=spec.pitch, width=config.layer_width
        )
    n_out = N_SUBSETS if config.loss == "ce" else N_CANDIDATES
    head = "logits" if config.loss == "ce" else "existence"
    return PointNet2(n_out, head=head, width=config.layer_width, radii=(0.3 * spec.pitch, 0.8 * spec.pitch))


def _batches(n: int, size: int, generator: torch.Generator) -> list[Tensor]:
    """A shuffled partition of ``range(n)``; a last batch of one joins the previous one
    (batch norm needs two samples)."""
    order = torch.randperm(n, generator=generator)
    batches = list(order.split(size))
    if len(batches) > 1 and len(batches[-1]) == 1:
        batches[-2] = torch.cat([batches[-2], batches.pop()])
    return batches


def _loss(model: ExistenceNetwork, config: TrainConfig, scenes: NineScenes, idx: Tensor, x: Tensor) -> Tensor:
    """Mean loss of the scenes ``idx`` (clouds ``x``)."""
    z = model.logits(x)
    if config.loss == "ce":
        target = torch.as_tensor(scenes.masks[idx.numpy()], device=x.device)
        return nn.functional.cross_entropy(z, target)
    assert scenes.problems is not None, "chamfer training needs the scenes' problems"
    chamfer = chamfer_loss(scaled_tanh(z), [scenes.problems[i] for i in idx.tolist()]).mean()
    return chamfer + config.logit_penalty * (z**2).mean()


def train(
    model: ExistenceNetwork,
    scenes: NineScenes,
    config: TrainConfig,
    *,
    log: Callable[[str], None] | None = None,
    device: torch.device | None = None,
) -> list[float]:
    """Trains ``model`` in place with Adam; returns the mean loss of every epoch."""
    device = device or default_device()
    model.to(device).train()
    clouds = torch.as_tensor(scenes.clouds, device=device)
    opt = torch.optim.Adam(model.parameters(), lr=config.learning_rate)
    generator = torch.Generator().manual_seed(config.seed)
    history = []
    for epoch in range(config.epochs):
        start, total = time.perf_counter(), 0.0
        for idx in _batches(len(scenes), config.batch_size, generator):
            opt.zero_grad()
            loss = _loss(model, config, scenes, idx, clouds[idx.to(device)])
            loss.backward()
            opt.step()
            total += loss.item() * len(idx)
        history.append(total / len(scenes))
        if log:
            log(f"epoch {epoch + 1}/{config.epochs}: loss {history[-1]:.4f} ({time.perf_counter() - start:.1f} s)")
    return history


@torch.no_grad()
def predict(model: nn.Module, clouds: np.ndarray, *, batch_size: int = 128, device: torch.device | None = None) -> np.ndarray:
    """Existences ``(S, 9)`` in [0, 1] (a subset classifier gives its argmax's bits)."""
    device = device or default_device()
    model.to(device).eval()
    out = []
    for chunk in torch.as_tensor(clouds).split(batch_size):
        y = model(chunk.to(device)).cpu()
        if y.shape[-1] == N_SUBSETS:
            y = torch.as_tensor(nine.bits(y.argmax(-1).numpy()))
        out.append(y.double())
    return torch.cat(out).numpy()


def score(existence: np.ndarray, masks: np.ndarray, threshold: float = 0.5) -> Scores:
    """Scores of existences ``(S, 9)`` thresholded at ``threshold`` against ``masks``."""
    found, truth = existence > threshold, nine.bits(masks) > 0.5
    right = found == truth
    return Scores(
        scene=float(right.all(axis=1).mean()),
        primitive=float(right.mean()),
        recall=float(found[truth].mean()) if truth.any() else math.nan,
        false_positive=float(found[~truth].mean()) if (~truth).any() else math.nan,
    )


def copies_for(masks: np.ndarray, scenes: int) -> int:
    """Copies of every mask so a split has about ``scenes`` scenes (at least one each)."""
    return max(1, round(scenes / len(masks)))


def _parser() -> argparse.ArgumentParser:
    d = TrainConfig()
    s = SceneSpec()
    p = argparse.ArgumentParser(prog="python -m primfit.research.train", description=__doc__.split("\n\n")[0])
    p.add_argument("--train", default="all", choices=sorted(SPLITS), help="training split (default all)")
    p.add_argument("--test", default="all", choices=sorted(SPLITS), help="test split (default all)")
    p.add_argument("--scenes", type=int, default=512, help="about this many training scenes (copies of the split)")
    p.add_argument("--test-scenes", type=int, default=512, help="about this many test scenes")
    p.add_argument("--arch", default=d.arch, choices=ARCHS)
    p.add_argument("--loss", default=d.loss, choices=LOSSES)
    p.add_argument("--epochs", type=int, default=d.epochs)
    p.add_argument("--batch-size", type=int, default=d.batch_size)
    p.add_argument("--lr", type=float, help=f"Adam step (default {DEFAULT_LR})")
    p.add_argument("--width", type=float, help=f"layer-width multiplier (default {DEFAULT_WIDTH})")
    p.add_argument("--points", type=int, default=s.points, help="points per scene")
    p.add_argument("--offset", type=float, default=0.0, help="largest alignment offset of the test scenes (pitches)")
    p.add_argument("--logit-penalty", type=float, default=d.logit_penalty, help="λ of λ·mean(z²) (chamfer loss)")
    p.add_argument("--seed", type=int, default=d.seed)
    p.add_argument("--threads", type=int, help="torch CPU threads (default torch's; 1 is often fastest on a small CPU)")
    p.add_argument("--save", help="write the trained weights here (torch.save of the state dict)")
    return p


def main(argv: Sequence[str] | None = None) -> Scores:
    """Trains one network and prints its scores on the test split."""
    a = _parser().parse_args(argv)
    if a.threads:
        torch.set_num_threads(a.threads)
    config = TrainConfig(a.arch, a.loss, a.epochs, a.batch_size, a.lr, a.width, a.seed, a.logit_penalty)
    spec = SceneSpec(points=a.points)
    train_masks, test_masks = split_masks(a.train), split_masks(a.test)
    train_set = nine.make_scenes(
        train_masks, copies=copies_for(train_masks, a.scenes), spec=spec, seed=a.seed * 1_000_000,
        problems=config.loss == "chamfer",
    )
    test_set = nine.make_scenes(
        test_masks, copies=copies_for(test_masks, a.test_scenes), spec=nine.with_offset(spec, a.offset),
        seed=a.seed * 1_000_000 + 500_000, problems=False,
    )
    model = build_model(config, spec)
    settings = {**asdict(config), "lr": config.learning_rate, "width": config.layer_width}
    print(f"{settings}; {len(train_set)} training scenes ({a.train}), {len(test_set)} test ({a.test})")
    start = time.perf_counter()
    train(model, train_set, config, log=print)
    print(f"trained in {time.perf_counter() - start:.1f} s on {default_device()}")
    result = score(predict(model, test_set.clouds), test_set.masks)
    print(f"test: {result}")
    if a.save:
        torch.save(model.state_dict(), a.save)
    return result


if __name__ == "__main__":
    main()
