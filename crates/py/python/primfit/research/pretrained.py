"""The existence networks shipped with primfit, and the command that trains them.

Both are trained on all 512 nine-cylinder subsets (thesis §5.5) with the chamfer loss
and the defaults of :class:`~primfit.research.train.TrainConfig`::

    from primfit.research import load_pretrained
    model = load_pretrained("pointnet2")           # or "local"; in eval mode, on the CPU
    existence = model(torch.as_tensor(clouds))     # (B, 256, 3) float32 → (B, 9) in [0, 1]

A weights file is a ``torch.save`` dict read back with ``weights_only=True`` (no pickled
code): the format number, the network's constructor arguments (``hparams``), the
:class:`TrainConfig` and :class:`SceneSpec` it was trained with, a card (training time,
machine, torch version, command) and the state dict.

Rebuild them (about a minute per network on 2 CPU cores)::

    python -m primfit.research.pretrained --out crates/py/python/primfit/research/weights
"""

from __future__ import annotations

import argparse
import os
import pickle
import platform
import time
from collections.abc import Sequence
from dataclasses import asdict
from pathlib import Path
from typing import Any

import torch

from . import nine
from .nine import SceneSpec
from .nn import ExistenceNetwork, LocalExistence, PointNet2
from .train import TrainConfig, build_model, split_masks, train

__all__ = ["FORMAT", "NAMES", "WEIGHTS", "load_pretrained", "pretrained_card", "save_pretrained", "train_pretrained"]

#: The shipped networks: the thesis's PointNet++ and the candidate-local network.
NAMES = ("pointnet2", "local")
#: Folder of the shipped weights (``<name>.pt``).
WEIGHTS = Path(__file__).with_name("weights")
#: Version of the weights file layout.
FORMAT = 1
#: Seed of the shipped networks' weights, batch order and training scenes.
SEED = 0


def _path(name: str, folder: Path | None) -> Path:
    if name not in NAMES:
        raise ValueError(f"no pretrained network {name!r}: choose one of {NAMES}")
    return (folder or WEIGHTS) / f"{name}.pt"


def _read(name: str, folder: Path | None) -> dict[str, Any]:
    path = _path(name, folder)
    try:
        doc = torch.load(path, map_location="cpu", weights_only=True)
    except FileNotFoundError:
        raise FileNotFoundError(f"{path}: the weights of {name!r} are missing from this installation") from None
    except (pickle.UnpicklingError, RuntimeError, EOFError) as e:
        raise ValueError(f"{path}: not a readable weights file ({str(e).splitlines()[0]})") from None
    if not isinstance(doc, dict) or doc.get("format") != FORMAT:
        raise ValueError(f"{path}: not a primfit weights file of format {FORMAT}")
    return doc


def pretrained_card(name: str, *, folder: Path | None = None) -> dict[str, Any]:
    """How network ``name`` was trained: ``config`` and ``spec`` (dicts), ``seconds``,
    ``machine``, ``threads``, ``torch`` and ``command``."""
    doc = _read(name, folder)
    return {"config": doc["config"], "spec": doc["spec"], **doc["card"]}


def load_pretrained(name: str, *, folder: Path | None = None) -> ExistenceNetwork:
    """The shipped network ``name`` (``"pointnet2"`` or ``"local"``), in eval mode on the
    CPU: clouds ``(B, points, 3)`` of the nine-cylinder scenes → existences ``(B, 9)``.

    ``folder`` reads another set of weights (as written by ``--out``).
    """
    doc = _read(name, folder)
    state = doc["state_dict"]
    if doc["config"]["arch"] == "local":
        frames = {"rotations": state["rotations"], "types": state["types"]}
        model: ExistenceNetwork = LocalExistence(state["centres"], **frames, **doc["hparams"])
    else:
        model = PointNet2(**doc["hparams"])
    model.load_state_dict(state)
    return model.eval()


def save_pretrained(path: Path, model: ExistenceNetwork, config: TrainConfig, spec: SceneSpec, card: dict[str, Any]) -> None:
    """Writes ``model`` with what :func:`load_pretrained` needs to rebuild it (atomically)."""
    doc = {
        "format": FORMAT,
        "hparams": model.hparams,
        "config": asdict(config),
        "spec": asdict(spec),
        "card": card,
        "state_dict": {k: v.detach().cpu() for k, v in model.state_dict().items()},
    }
    tmp = path.with_name(path.name + ".tmp")
    torch.save(doc, tmp)
    os.replace(tmp, path)


def train_pretrained(name: str, *, seed: int = SEED, log=print) -> tuple[ExistenceNetwork, TrainConfig, SceneSpec, float]:
    """Trains network ``name`` as shipped: all 512 subsets, one scene each, the
    :class:`TrainConfig` defaults. Returns the model, its config and spec, and seconds."""
    config = TrainConfig(arch=name, seed=seed)
    spec = SceneSpec()
    scenes = nine.make_scenes(split_masks("all"), spec=spec, seed=seed * 1_000_000)
    model = build_model(config, spec)
    start = time.perf_counter()
    train(model, scenes, config, device=torch.device("cpu"), log=log)
    return model, config, spec, time.perf_counter() - start


def _machine() -> str:
    return f"{platform.processor() or platform.machine()}, {os.cpu_count()} logical CPUs, {platform.system()}"


def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="python -m primfit.research.pretrained", description=__doc__.split("\n\n")[0])
    p.add_argument("--out", required=True, help="folder for <name>.pt")
    p.add_argument("--models", nargs="+", default=list(NAMES), choices=NAMES)
    p.add_argument("--threads", type=int, help="torch CPU threads (default torch's)")
    return p


def main(argv: Sequence[str] | None = None) -> None:
    """Trains and writes the shipped networks."""
    a = _parser().parse_args(argv)
    if a.threads:
        torch.set_num_threads(a.threads)
    out = Path(a.out)
    out.mkdir(parents=True, exist_ok=True)
    for name in a.models:
        model, config, spec, seconds = train_pretrained(name, log=lambda line: print(f"{name}: {line}"))
        card = {
            "seconds": seconds,
            "machine": _machine(),
            "threads": torch.get_num_threads(),
            "torch": str(torch.__version__),
            "command": f"python -m primfit.research.pretrained --out DIR --models {name}",
        }
        save_pretrained(_path(name, out), model, config, spec, card)
        print(f"{name}: trained in {seconds:.1f} s, wrote {_path(name, out)}")


if __name__ == "__main__":
    main()
