"""Scores of a shipped network on fresh held-out nine-cylinder scenes.

    python -m primfit.research.experiments evaluate --model pointnet2 --scenes 1000 --seed 1 --json

Scene ``s`` of seed ``S`` has a subset drawn uniformly from the split's masks by a
generator seeded with ``S``, and noise seeded with ``HELD_OUT_SEEDS + S · MAX_SCENES + s``:
a range no training run uses (training scenes are seeded from 0 up, see
:func:`primfit.research.nine.make_scenes`), so every scene is new to the network.
"""

from __future__ import annotations

import math
import time
from dataclasses import asdict, replace
from typing import Any

import numpy as np

from . import nine
from .nine import NineScenes, SceneSpec

__all__ = ["HELD_OUT_SEEDS", "MAX_SCENES", "evaluate", "held_out_scenes"]

#: First noise seed of the held-out scenes (2⁴⁰: far above any training seed).
HELD_OUT_SEEDS = 1 << 40
#: Most scenes one evaluation draws (keeps the seeds of two evaluation seeds apart).
MAX_SCENES = 1_000_000


def held_out_scenes(n: int, seed: int, spec: SceneSpec, split: str = "all") -> NineScenes:
    """``n`` fresh scenes of ``split`` (``all``, ``single``, ``pairs``, ``multi``) for
    ``seed``, made with ``spec`` (its ``offset`` included); no chamfer problems."""
    from .train import split_masks

    if not 1 <= n <= MAX_SCENES:
        raise ValueError(f"--scenes must be in 1..{MAX_SCENES}, got {n}")
    if seed < 0:
        raise ValueError(f"--seed must be >= 0, got {seed}")
    masks = np.random.default_rng(seed).choice(split_masks(split), size=n)
    return nine.make_scenes(masks, spec=spec, seed=HELD_OUT_SEEDS + seed * MAX_SCENES, problems=False)


def evaluate(name: str, scenes: int, seed: int, *, offset: float = 0.0, split: str = "all") -> dict[str, Any]:
    """Runs shipped network ``name`` on :func:`held_out_scenes` (with alignment
    ``offset`` in pitches) and returns its scores (existence thresholded at 0.5) as a
    JSON-ready dict: ``scene_accuracy``, ``primitive_accuracy``, ``recall``,
    ``false_positive_rate``, the inputs, and ``seconds`` of inference."""
    from .pretrained import load_pretrained, pretrained_card
    from .train import predict, score

    model = load_pretrained(name)
    spec = replace(SceneSpec(**pretrained_card(name)["spec"]), offset=offset)
    held_out = held_out_scenes(scenes, seed, spec, split)
    start = time.perf_counter()
    existence = predict(model, held_out.clouds, device=_cpu())
    seconds = time.perf_counter() - start
    s = score(existence, held_out.masks)
    return {
        "model": name,
        "scenes": scenes,
        "seed": seed,
        "split": split,
        "offset": offset,
        "scene_accuracy": s.scene,
        "primitive_accuracy": s.primitive,
        "recall": _json_number(s.recall),
        "false_positive_rate": _json_number(s.false_positive),
        "seconds": seconds,
        "spec": asdict(spec),
    }


def _cpu():
    import torch

    return torch.device("cpu")


def _json_number(v: float) -> float | None:
    """NaN (no true or no absent cylinder among the scenes) as JSON null."""
    return None if math.isnan(v) else v
