"""Heatmaps of the six-in-a-row negative log-likelihoods (thesis fig. 4-4).

Reads six_squares.csv and six_cylinders.csv written by the `ray_toy_heatmap` example and
writes ray_toy_heatmap.png beside them. Colour: log10(1 + NLL - best NLL), darker = more
likely; each cell is annotated with NLL - best (nats).

    python3 examples/ray_toy_heatmap.py OUT_DIR
"""
import csv
import math
import sys
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402


def read(path):
    with open(path, newline="") as f:
        rows = list(csv.reader(f))
    labels = [float(x) for x in rows[0][1:]]
    matrix = [[float(x) for x in r[1:]] for r in rows[1:]]
    return labels, matrix


def panel(ax, title, labels, matrix):
    best = min(min(r) for r in matrix)
    rel = [[v - best for v in r] for r in matrix]
    shade = [[math.log10(1.0 + v) for v in r] for r in rel]
    im = ax.imshow(shade, cmap="magma", origin="upper")
    ticks = [f"{x:g} m" for x in labels]
    ax.set_xticks(range(len(labels)), ticks)
    ax.set_yticks(range(len(labels)), ticks)
    ax.set_xlabel("candidate k")
    ax.set_ylabel("candidate i")
    ax.set_title(title)
    top = max(max(r) for r in shade)
    for i, r in enumerate(rel):
        for k, v in enumerate(r):
            colour = "white" if shade[i][k] < 0.6 * top else "black"
            ax.text(k, i, f"{v:.3g}", ha="center", va="center", fontsize=7, color=colour)
    return im


def main():
    out = Path(sys.argv[1] if len(sys.argv) > 1 else "target/ray_toy")
    fig, axes = plt.subplots(1, 2, figsize=(11, 5), constrained_layout=True)
    for ax, (name, title) in zip(
        axes, [("six_squares", "planar candidates"), ("six_cylinders", "cylindrical candidates")]
    ):
        labels, matrix = read(out / f"{name}.csv")
        im = panel(ax, title, labels, matrix)
    fig.colorbar(im, ax=axes, label="log10(1 + NLL - best)  (darker = more likely)")
    fig.suptitle("Negative log-likelihood of single (diagonal) and double candidate scenes")
    path = out / "ray_toy_heatmap.png"
    fig.savefig(path, dpi=110)
    print(f"wrote {path}")


if __name__ == "__main__":
    main()
