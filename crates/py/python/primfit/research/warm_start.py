"""A network's existence as the starting point of the chamfer solver.

The fit minimises the probabilistic chamfer over existence with projected L-BFGS from
p = 0.5 for every candidate (:meth:`primfit.ChamferProblem.solve`). A network that has
learnt existence can give a better start; this module measures what that saves, in
L-BFGS iterations and wall time (the network's own time included), on

* the nine-cylinder scenes, with the shipped networks (:mod:`~primfit.research.pretrained`);
* the pipe (``examples/pipe.ply`` and held-out synthetic pipes): the candidate-local
  network, with each candidate's frame and type, trained here on synthetic pipes over
  the lattice of the README's worked example to predict the solver's decision.

Run::

    python -m primfit.research.warm_start --pipe examples/pipe.ply --json
"""

from __future__ import annotations

import argparse
import json
import time
from collections.abc import Sequence
from dataclasses import asdict, dataclass
from typing import Any

import numpy as np
import torch

import primfit

from . import nine
from .nn import LocalExistence, scaled_tanh

__all__ = [
    "PIPE_OPTIONS",
    "PipeScene",
    "SolveCost",
    "nine_cylinder_study",
    "pipe_network",
    "pipe_scene",
    "pipe_study",
    "train_pipe_network",
]

#: The lattice of the README's worked example (``primfit fit pipe.ply --types
#: cylinder,elbow --size 1 --radius 0.1 --bend 0.5 --spacing 0.5 --frame axis --no-refine``).
PIPE_OPTIONS: dict[str, Any] = {
    "types": ["cylinder", "elbow"],
    "size": 1.0,
    "radius": 0.1,
    "bend": 0.5,
    "spacing": 0.5,
    "frame": "axis",
    "refine": False,
}
PIPE_TYPES = ("cylinder", "elbow")
#: Seeds of the synthetic training pipes, and of the held-out ones (the bundled
#: example is seed 3, outside both).
TRAIN_PIPE_SEEDS = range(100, 116)
TEST_PIPE_SEEDS = range(1000, 1010)


@dataclass(frozen=True)
class PipeScene:
    """One cloud over the pipe lattice: its loss, and its candidates as the network sees
    them (centre = mean of the candidate's samples, frame from its pose, type)."""

    cloud: np.ndarray
    problem: primfit.ChamferProblem
    centres: np.ndarray
    rotations: np.ndarray
    types: np.ndarray


def _rotation(q: Sequence[float]) -> np.ndarray:
    """The 3 × 3 matrix of a unit quaternion ``(w, x, y, z)``."""
    w, x, y, z = q
    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
            [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
            [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
        ]
    )


def pipe_scene(cloud: np.ndarray) -> PipeScene:
    """The candidates and loss of the pipe lattice (:data:`PIPE_OPTIONS`) on ``cloud``."""
    c = primfit.candidates(cloud, **PIPE_OPTIONS)
    n = len(c)
    counts = np.bincount(c.owner, minlength=n)[:, None]
    centres = np.stack([np.bincount(c.owner, weights=c.samples[:, d], minlength=n) for d in range(3)], axis=1) / counts
    rotations = np.stack([_rotation(p["pose"]["rotation"]) for p in c.primitives])
    types = np.array([PIPE_TYPES.index(p["type"]) for p in c.primitives])
    return PipeScene(np.asarray(cloud, np.float32), c.problem(), centres, rotations, types)


def pipe_network(seed: int = 0) -> LocalExistence:
    """An untrained candidate-local network for the pipe lattice (radius 0.7 · size)."""
    torch.manual_seed(seed)
    size = PIPE_OPTIONS["size"]
    return LocalExistence(np.zeros((0, 3)), radius=0.7 * size, scale=size, n_types=len(PIPE_TYPES))


def _inputs(model: LocalExistence, scene: PipeScene) -> tuple[torch.Tensor, torch.Tensor]:
    """Sets the scene's candidates on ``model``; returns their neighbourhoods."""
    model.set_candidates(scene.centres, scene.rotations, scene.types)
    with torch.no_grad():
        return model.neighbourhoods(torch.as_tensor(scene.cloud)[None])


def train_pipe_network(
    scenes: Sequence[PipeScene], *, epochs: int = 20, lr: float = 3e-3, seed: int = 0, log=None
) -> LocalExistence:
    """Trains :func:`pipe_network` on ``scenes`` to predict the solver's decision (Adam,
    one scene per step, binary cross-entropy against ``problem.solve(0.5).exists``).

    Still self-supervised (no ground truth: the targets are the Rust loss's own
    minimiser), but not by the loss itself: on the pipe lattice the chamfer loss of a
    start at p = 0.5 is five orders of magnitude above the answer's, and a network
    trained on it learns "nothing exists" (loss 1985 against ≈ 1 at the answer) before
    it learns which candidates do; see docs/nn_results.md.
    """
    model = pipe_network(seed)
    inputs = [_inputs(model, s) for s in scenes]  # fixed: computed once
    targets = [torch.as_tensor(s.problem.solve(0.5).exists, dtype=torch.float32)[None] for s in scenes]
    opt = torch.optim.Adam(model.parameters(), lr=lr)
    order = torch.Generator().manual_seed(seed)
    for epoch in range(epochs):
        total = 0.0
        for i in torch.randperm(len(scenes), generator=order).tolist():
            s = scenes[i]
            model.set_candidates(s.centres, s.rotations, s.types)
            opt.zero_grad()
            # scaled_tanh(z) = σ(2z): cross-entropy on the logit 2z.
            z = model.logits_of(*inputs[i])
            loss = torch.nn.functional.binary_cross_entropy_with_logits(2 * z, targets[i])
            loss.backward()
            opt.step()
            total += loss.item()
        if log:
            log(f"epoch {epoch + 1}/{epochs}: loss {total / len(scenes):.4f}")
    return model.eval()


@dataclass(frozen=True)
class SolveCost:
    """Cold (p = 0.5) and warm (network) solves of a set of problems, summed.

    ``network_seconds`` is the network's time (neighbourhoods and forward pass);
    ``same_answer`` the share of problems where both decide the same existence;
    ``warm_loss_ratio`` the warm answer's binary loss over the cold one's (mean).
    """

    problems: int
    cold_iterations: int
    warm_iterations: int
    cold_evaluations: int
    warm_evaluations: int
    cold_seconds: float
    warm_seconds: float
    network_seconds: float
    same_answer: float
    warm_loss_ratio: float


def _compare(problems: Sequence[primfit.ChamferProblem], starts: Sequence[np.ndarray], network_seconds: float) -> SolveCost:
    rows = []
    for problem, start in zip(problems, starts):
        t0 = time.perf_counter()
        cold = problem.solve(0.5)
        t1 = time.perf_counter()
        warm = problem.solve(np.clip(start, 0.0, 1.0))
        t2 = time.perf_counter()
        same = bool(np.array_equal(cold.exists, warm.exists))
        ratio = warm.binary / cold.binary if cold.binary > 0 else 1.0
        rows.append((cold.iterations, warm.iterations, cold.evaluations, warm.evaluations, t1 - t0, t2 - t1, same, ratio))
    a = np.array(rows, dtype=float)
    return SolveCost(
        problems=len(rows),
        cold_iterations=int(a[:, 0].sum()),
        warm_iterations=int(a[:, 1].sum()),
        cold_evaluations=int(a[:, 2].sum()),
        warm_evaluations=int(a[:, 3].sum()),
        cold_seconds=float(a[:, 4].sum()),
        warm_seconds=float(a[:, 5].sum()),
        network_seconds=network_seconds,
        same_answer=float(a[:, 6].mean()),
        warm_loss_ratio=float(a[:, 7].mean()),
    )


def nine_cylinder_study(name: str, scenes: int = 500, seed: int = 0) -> SolveCost:
    """Cold and warm solves of ``scenes`` held-out nine-cylinder scenes (the empty scene,
    which has no problem to solve, is left out), warm from shipped network ``name``."""
    from .evaluate import held_out_scenes
    from .pretrained import load_pretrained

    model = load_pretrained(name)
    held_out = held_out_scenes(scenes, seed, nine.SceneSpec())
    keep = held_out.masks != 0
    clouds = held_out.clouds[keep]
    problems = nine._problems(list(clouds), held_out.masks[keep], held_out.spec)
    start = time.perf_counter()
    with torch.no_grad():
        existence = model(torch.as_tensor(clouds)).double().numpy()
    network = time.perf_counter() - start
    return _compare(problems, list(existence), network)  # type: ignore[arg-type]


def pipe_study(model: LocalExistence, scenes: Sequence[PipeScene]) -> SolveCost:
    """Cold and warm solves of the pipe ``scenes``, warm from ``model``."""
    starts = []
    start = time.perf_counter()
    for s in scenes:
        with torch.no_grad():
            starts.append(scaled_tanh(model.logits_of(*_inputs(model, s)))[0].double().numpy())
    network = time.perf_counter() - start
    return _compare([s.problem for s in scenes], starts, network)


def _pipe_clouds(seeds: Sequence[int]) -> list[np.ndarray]:
    """Synthetic pipes of 3–6 runs (the count drawn from the seed)."""
    return [primfit.synth.pipe(segments=3 + seed % 4, seed=seed)[0] for seed in seeds]


def main(argv: Sequence[str] | None = None) -> dict[str, Any]:
    """Measures cold and warm solves on the nine-cylinder scenes and the pipe."""
    p = argparse.ArgumentParser(prog="python -m primfit.research.warm_start", description=__doc__.split("\n\n")[0])
    p.add_argument("--pipe", default="examples/pipe.ply", help="the bundled pipe scan (default examples/pipe.ply)")
    p.add_argument("--scenes", type=int, default=500, help="held-out nine-cylinder scenes (default 500)")
    p.add_argument("--epochs", type=int, default=20, help="training epochs of the pipe network (default 20)")
    p.add_argument("--json", action="store_true", help="print one JSON object")
    a = p.parse_args(argv)
    log = None if a.json else print
    out: dict[str, Any] = {}
    for name in ("pointnet2", "local"):
        out[f"nine_cylinders/{name}"] = asdict(nine_cylinder_study(name, a.scenes, seed=0))
    start = time.perf_counter()
    train_scenes = [pipe_scene(c) for c in _pipe_clouds(TRAIN_PIPE_SEEDS)]
    model = train_pipe_network(train_scenes, epochs=a.epochs, log=log)
    out["pipe/training_seconds"] = time.perf_counter() - start
    bundled = pipe_scene(primfit.read(a.pipe)["points"])
    out["pipe/bundled"] = asdict(pipe_study(model, [bundled]))
    out["pipe/held_out"] = asdict(pipe_study(model, [pipe_scene(c) for c in _pipe_clouds(TEST_PIPE_SEEDS)]))
    print(json.dumps(out, indent=None if a.json else 1))
    return out


if __name__ == "__main__":
    main()
