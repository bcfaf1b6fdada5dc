"""The thesis's chapter-5 experiments on the nine-cylinder scenes, as one command.

    python -m primfit.research.experiments table --out results/      # Table 5.1, figure 5-2
    python -m primfit.research.experiments evaluate --model pointnet2 --scenes 1000 --seed 1 --json

Trains, for each of Table 5.1's rows (all → all, multi → single, single → pairs), the
thesis's PointNet++ with the self-supervised probabilistic chamfer loss, the same
backbone with the supervised 512-class cross-entropy, and the candidate-local network
(:class:`primfit.research.nn.LocalExistence`) with the chamfer loss; then tests each all → all
model on scenes with growing alignment offset (thesis figure 5-2). Writes

* ``results.md``: the table (ours beside the thesis's numbers), timings, settings;
* ``results.json``: every score, loss curve and time;
* ``offset_sweep.png`` and ``training_loss.png``.

Runs go to ``--jobs`` worker processes (one torch thread each: on a small shared CPU
that is much faster than threads for these small tensors). ``--quick`` is a
two-minute check of the pipeline, not of the results.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from collections.abc import Sequence
from concurrent.futures import ProcessPoolExecutor
from dataclasses import asdict, dataclass, field, replace
from multiprocessing import get_context
from pathlib import Path

import numpy as np

__all__ = ["ExperimentConfig", "Job", "JobResult", "main", "run_all", "run_job", "write_report"]

#: Table 5.1's rows: (training split, test split, label). The thesis tests
#: single-trained networks on pairs of cylinders.
ROWS = (("all", "all", "all → all"), ("multi", "single", "multi → single"), ("single", "pairs", "single → pairs"))
#: The networks compared: (arch, loss, label).
MODELS = (
    ("pointnet2", "chamfer", "PointNet++ · chamfer"),
    ("pointnet2", "ce", "PointNet++ · cross-entropy"),
    ("local", "chamfer", "local · chamfer"),
)
#: Thesis Table 5.1 (scene, primitive) and §5.5's cross-entropy number (scene only).
THESIS = {
    ("all", "chamfer"): (0.96, 0.98),
    ("multi", "chamfer"): (0.85, 0.85),
    ("single", "chamfer"): (0.05, 0.33),
    ("all", "ce"): (0.98, None),
}


@dataclass(frozen=True)
class ExperimentConfig:
    """Sizes of the experiment (defaults: the full run, about 5 min on 2 shared CPU cores)."""

    points: int = 256
    scenes: int = 512
    test_scenes: int = 512
    epochs: int = 40
    batch_size: int = 32
    lr_pointnet2: float = 1e-2
    lr_local: float = 3e-3
    width_pointnet2: float = 0.5
    width_local: float = 1.0
    offsets: tuple[float, ...] = (0.0, 0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.7, 0.8, 0.9, 1.0)
    seed: int = 0
    threads: int = 1


@dataclass(frozen=True)
class Job:
    """One training run and its tests."""

    arch: str
    loss: str
    train: str
    test: str
    config: ExperimentConfig
    sweep: bool = False


@dataclass
class JobResult:
    """What one run measured."""

    job: Job
    scores: dict[str, float]
    history: list[float]
    train_seconds: float
    sweep: list[dict[str, float]] = field(default_factory=list)


def _test_scores(model, masks: np.ndarray, spec, copies: int, seed: int) -> dict[str, float]:
    from . import nine
    from .train import predict, score

    scenes = nine.make_scenes(masks, copies=copies, spec=spec, seed=seed, problems=False)
    return asdict(score(predict(model, scenes.clouds), scenes.masks))


def run_job(job: Job) -> JobResult:
    """Trains one network and scores it (and sweeps the offset when ``job.sweep``)."""
    import torch

    from . import nine
    from .train import TrainConfig, build_model, copies_for, split_masks, train

    c = job.config
    torch.set_num_threads(c.threads)
    local = job.arch == "local"
    width, lr = (c.width_local, c.lr_local) if local else (c.width_pointnet2, c.lr_pointnet2)
    config = TrainConfig(job.arch, job.loss, c.epochs, c.batch_size, lr, width, c.seed)
    spec = nine.SceneSpec(points=c.points)
    train_masks, test_masks = split_masks(job.train), split_masks(job.test)
    scenes = nine.make_scenes(
        train_masks, copies=copies_for(train_masks, c.scenes), spec=spec, seed=c.seed * 1_000_000,
        problems=job.loss == "chamfer",
    )
    model = build_model(config, spec)
    start = time.perf_counter()
    history = train(model, scenes, config)
    seconds = time.perf_counter() - start
    test_seed = c.seed * 1_000_000 + 500_000
    scores = _test_scores(model, test_masks, spec, copies_for(test_masks, c.test_scenes), test_seed)
    sweep = []
    if job.sweep:
        for k, offset in enumerate(c.offsets):
            s = _test_scores(model, test_masks, nine.with_offset(spec, offset), 1, test_seed + 10_000 * (k + 1))
            sweep.append({"offset": offset, **s})
    return JobResult(job, scores, history, seconds, sweep)


def jobs_for(config: ExperimentConfig) -> list[Job]:
    """Every run of the experiment, slowest first (better packing on the workers)."""
    jobs = [
        Job(arch, loss, train, test, config, sweep=train == "all")
        for arch, loss, _ in MODELS
        for train, test, _ in ROWS
    ]
    return sorted(jobs, key=lambda j: j.arch != "pointnet2")


def run_all(config: ExperimentConfig, workers: int, log=print) -> list[JobResult]:
    """Runs every job on ``workers`` processes; results in :func:`jobs_for` order."""
    jobs = jobs_for(config)
    if workers <= 1:
        results = []
        for job in jobs:
            results.append(run_job(job))
            log(_summary(results[-1]))
        return results
    with ProcessPoolExecutor(workers, mp_context=get_context("spawn")) as pool:
        futures = [pool.submit(run_job, job) for job in jobs]
        results = []
        for f in futures:
            results.append(f.result())
            log(_summary(results[-1]))
    return results


def _summary(r: JobResult) -> str:
    j = r.job
    return (
        f"{j.arch} {j.loss} {j.train}→{j.test}: scene {r.scores['scene']:.3f}, "
        f"primitive {r.scores['primitive']:.3f} (trained {r.train_seconds:.0f} s)"
    )


def _find(results: Sequence[JobResult], arch: str, loss: str, train: str) -> JobResult | None:
    return next((r for r in results if (r.job.arch, r.job.loss, r.job.train) == (arch, loss, train)), None)


def _pair(scene: float | None, primitive: float | None) -> str:
    f = lambda v: "–" if v is None else f"{v:.2f}"  # noqa: E731
    return f"{f(scene)} / {f(primitive)}"


def table(results: Sequence[JobResult]) -> str:
    """Markdown table: scene / primitive accuracy per row and network, thesis beside."""
    head = "| train → test | thesis (chamfer) | " + " | ".join(m[2] for m in MODELS) + " |"
    lines = [head, "|" + "---|" * (2 + len(MODELS))]
    for train, _, label in ROWS:
        cells = [_pair(*THESIS[(train, "chamfer")])]
        for arch, loss, _ in MODELS:
            r = _find(results, arch, loss, train)
            cells.append("n/a" if r is None else _pair(r.scores["scene"], r.scores["primitive"]))
        lines.append(f"| {label} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def detail_table(results: Sequence[JobResult]) -> str:
    """Markdown table of every run: all four scores and the training time."""
    lines = [
        "| network | train → test | scene | primitive | recall | false positives | training (s) |",
        "|---|---|---|---|---|---|---|",
    ]
    labels = {(a, lo): lab for a, lo, lab in MODELS}
    for r in results:
        s, j = r.scores, r.job
        lines.append(
            f"| {labels[(j.arch, j.loss)]} | {j.train} → {j.test} | {s['scene']:.3f} | {s['primitive']:.3f} | "
            f"{s['recall']:.3f} | {s['false_positive']:.3f} | {r.train_seconds:.0f} |"
        )
    return "\n".join(lines)


def _plots(results: Sequence[JobResult], out: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    labels = {(a, lo): lab for a, lo, lab in MODELS}
    fig, axes = plt.subplots(1, 2, figsize=(10, 4), sharey=True)
    for r in results:
        if not r.sweep:
            continue
        x = [s["offset"] for s in r.sweep]
        for ax, key in zip(axes, ("scene", "primitive")):
            ax.plot(x, [s[key] for s in r.sweep], marker="o", label=labels[(r.job.arch, r.job.loss)])
    for ax, key in zip(axes, ("scene", "primitive")):
        ax.set(xlabel="maximum offset (pitches)", title=f"{key} accuracy (trained aligned, all → all)", ylim=(0, 1.02))
        ax.grid(alpha=0.3)
    axes[0].set_ylabel("accuracy")
    axes[1].legend()
    fig.tight_layout()
    fig.savefig(out / "offset_sweep.png", dpi=120)
    plt.close(fig)

    fig, axes = plt.subplots(1, len(ROWS), figsize=(12, 3.5))
    for ax, (train, test, label) in zip(axes, ROWS):
        for arch, loss, mlabel in MODELS:
            run = _find(results, arch, loss, train)
            if run is not None and loss == "chamfer":
                ax.plot(np.arange(1, len(run.history) + 1), run.history, label=mlabel)
        ax.set(title=f"{label}: chamfer loss", xlabel="epoch", yscale="log")
        ax.grid(alpha=0.3)
    axes[0].legend()
    fig.tight_layout()
    fig.savefig(out / "training_loss.png", dpi=120)
    plt.close(fig)


def write_report(results: Sequence[JobResult], config: ExperimentConfig, seconds: float, out: Path) -> None:
    """Writes results.md, results.json and the PNGs to ``out``."""
    out.mkdir(parents=True, exist_ok=True)
    _plots(results, out)
    sweep_rows = ["| max offset | " + " | ".join(m[2] for m in MODELS) + " |", "|---|" + "---|" * len(MODELS)]
    for k, offset in enumerate(config.offsets):
        cells = []
        for arch, loss, _ in MODELS:
            r = _find(results, arch, loss, "all")
            cells.append("n/a" if r is None or not r.sweep else _pair(r.sweep[k]["scene"], r.sweep[k]["primitive"]))
        sweep_rows.append(f"| {offset:.1f} | " + " | ".join(cells) + " |")
    md = [
        "# Nine-cylinder experiments (thesis §5.5)",
        "",
        "Scene / primitive accuracy on held-out scenes (different jitter and drift).",
        "",
        table(results),
        "",
        "Thesis, cross-entropy all → all: scene accuracy 0.98.",
        "",
        "## Every run",
        "",
        detail_table(results),
        "",
        "## Alignment offset (all → all models; figure 5-2)",
        "",
        "\n".join(sweep_rows),
        "",
        "![offset sweep](offset_sweep.png)",
        "",
        "![training loss](training_loss.png)",
        "",
        f"Total wall time {seconds:.0f} s. Settings: `{json.dumps(asdict(config))}`",
        "",
    ]
    (out / "results.md").write_text("\n".join(md))
    doc = {
        "config": asdict(config),
        "seconds": seconds,
        "runs": [
            {**asdict(r.job), "config": None, "scores": r.scores, "history": r.history,
             "train_seconds": r.train_seconds, "sweep": r.sweep}
            for r in results
        ],
    }
    (out / "results.json").write_text(json.dumps(doc, indent=1))


def _table_arguments(p: argparse.ArgumentParser) -> None:
    d = ExperimentConfig()
    p.add_argument("--out", default="results", help="output folder (default results/)")
    p.add_argument("--jobs", type=int, default=min(2, os.cpu_count() or 1), help="worker processes")
    p.add_argument("--epochs", type=int, default=d.epochs)
    p.add_argument("--points", type=int, default=d.points, help="points per scene")
    p.add_argument("--scenes", type=int, default=d.scenes, help="about this many training scenes per run")
    p.add_argument("--test-scenes", type=int, default=d.test_scenes)
    p.add_argument("--width-pointnet2", type=float, default=d.width_pointnet2, help="PointNet++ width multiplier")
    p.add_argument("--lr-pointnet2", type=float, default=d.lr_pointnet2, help="PointNet++ Adam step")
    p.add_argument("--seed", type=int, default=d.seed)
    p.add_argument("--threads", type=int, default=d.threads, help="torch threads per worker")
    p.add_argument("--quick", action="store_true", help="tiny sizes: checks the pipeline in about two minutes")


def _evaluate_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--model", required=True, choices=("pointnet2", "local"), help="shipped network")
    p.add_argument("--scenes", type=int, default=1000, help="held-out scenes to draw (default 1000)")
    p.add_argument("--seed", type=int, default=0, help="seed of the held-out scenes (default 0)")
    p.add_argument("--split", default="all", choices=("all", "multi", "pairs", "single"), help="which subsets")
    p.add_argument("--offset", type=float, default=0.0, help="largest alignment offset, in pitches (default 0)")
    p.add_argument("--json", action="store_true", help="print the scores as one JSON object")


def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="python -m primfit.research.experiments", description=__doc__.split("\n\n")[0])
    commands = p.add_subparsers(dest="command", metavar="{table,evaluate}")
    _table_arguments(commands.add_parser("table", help="train every network of Table 5.1 and write the report (default)"))
    _evaluate_arguments(commands.add_parser("evaluate", help="score a shipped network on fresh held-out scenes"))
    return p


def _with_command(argv: Sequence[str]) -> list[str]:
    """``argv`` with ``table`` in front when it names no command (the old form)."""
    argv = list(argv)
    return argv if argv and argv[0] in ("table", "evaluate", "-h", "--help") else ["table", *argv]


def _evaluate(a: argparse.Namespace) -> None:
    from .evaluate import evaluate

    result = evaluate(a.model, a.scenes, a.seed, offset=a.offset, split=a.split)
    if a.json:
        print(json.dumps(result))
        return
    print(
        f"{a.model} on {a.scenes} held-out scenes (seed {a.seed}, {a.split}, offset {a.offset}): "
        f"scene accuracy {result['scene_accuracy']:.3f}, primitive accuracy {result['primitive_accuracy']:.3f}, "
        f"recall {result['recall']}, false positives {result['false_positive_rate']}"
    )


def main(argv: Sequence[str] | None = None) -> None:
    """Runs the experiment and writes the report, or evaluates a shipped network."""
    parser = _parser()
    a = parser.parse_args(_with_command(sys.argv[1:] if argv is None else argv))
    if a.command == "evaluate":
        try:
            _evaluate(a)
        except (ValueError, OSError) as e:
            parser.error(str(e))
        return
    config = ExperimentConfig(
        points=a.points, scenes=a.scenes, test_scenes=a.test_scenes, epochs=a.epochs, seed=a.seed, threads=a.threads,
        width_pointnet2=a.width_pointnet2, lr_pointnet2=a.lr_pointnet2,
    )
    if a.quick:
        config = replace(config, points=128, scenes=128, test_scenes=128, epochs=2, offsets=(0.0, 0.5, 1.0))
    start = time.perf_counter()
    results = run_all(config, a.jobs)
    seconds = time.perf_counter() - start
    write_report(results, config, seconds, Path(a.out))
    print(table(results))
    print(f"wrote {a.out}/results.md in {seconds:.0f} s")


if __name__ == "__main__":
    main()
