#!/usr/bin/env python3
"""Fits the registration confidence (``register/confidence.rs``) on benchmark answers.

Runs ``crates/core/examples/registration_bench.rs`` on the calibration scenes (seeds from
``--first-seed``, 100 by default, so the benchmark's seeds 0–4 stay held out): whole
surface and partial views of the procedural object and the Stanford bunny, partial
views with structured clutter, and scenes without the object (every answer there is
wrong). Each answer is right when its rotation error is < 5° and its translation error
< 2 % of the model size. The existence is ``σ(b + w_z·z + w_g·min(z − max(z₂, 0), cap))``
(``z`` the margin, ``z₂`` the best other answer's); the coefficients are fitted by
L2-regularised logistic regression (λ = 1, Newton's method, no intercept penalty).

    python3 benches/calibrate_confidence.py [--seeds 4] [--first-seed 100]
        [--out FILE.md] [--runs FILE.jsonl] [--save-runs FILE.jsonl]
        [--bench-args='--accept 0.5'] [--sensors-only]

The existence has one calibration for clouds with sensor origins (fit it with
``--sensors-only``: the partial views) and one for clouds without (fit it with
``--bench-args=--no-sensors``, every scene with its origins dropped).

Prints the coefficients, the answers table and a reliability table of the fitted
existence (markdown). ``--runs`` reuses the answers of an earlier run instead of
registering again. Pure Python: no numpy needed.
"""

import argparse
import json
import math
import os
import subprocess
import sys

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
BENCH = os.path.join(ROOT, "target", "release", "examples", "registration_bench")
BUNNY = os.path.join(ROOT, "..", "shared", "data", "bunny.ply")
GAP_CAP = 10.0  # confidence::GAP_CAP
LAMBDA = 1.0

# (label, outlier levels, registration_bench flags)
SCENES = [
    ("proc whole", "0.8,0.95", ["--inliers", "100"]),
    ("proc partial", "0.5,0.8,0.9,0.95", ["--inliers", "200", "--partial"]),
    ("proc clutter", "0.8,0.9", ["--inliers", "200", "--partial", "--clutter"]),
    ("proc absent", "0.9", ["--inliers", "200", "--partial", "--clutter", "--absent"]),
    ("proc absent whole", "0.95", ["--inliers", "100", "--absent"]),
    ("bun whole", "0.9", ["--inliers", "100", "--model", BUNNY]),
    ("bun partial", "0.8,0.9", ["--inliers", "400", "--partial", "--model", BUNNY]),
    ("bun absent", "0.9", ["--inliers", "400", "--partial", "--clutter", "--absent",
                           "--model", BUNNY]),
]


def run_scenes(seeds, first_seed, extra, sensors_only):
    """Every calibration answer: dicts of the bench's JSON plus ``scenes``."""
    answers = []
    for label, levels, flags in SCENES:
        if sensors_only and "--partial" not in flags:
            continue  # whole-surface scenes carry no sensor origins
        cmd = [BENCH, "--levels", levels, "--seeds", str(seeds),
               "--first-seed", str(first_seed)] + flags + extra
        print(f"{label}: {' '.join(cmd[1:])}", file=sys.stderr, flush=True)
        out = subprocess.run(cmd, check=True, capture_output=True, text=True).stdout
        for line in out.splitlines():
            if line.startswith("{"):
                row = json.loads(line)
                row["scenes"] = label
                answers.append(row)
    return answers


def is_right(a):
    return (a.get("found") and a.get("present", True) and a["rotation_deg"] < 5.0
            and a["translation_rel"] < 0.02)


def features(a):
    z = a.get("margin", 0.0)
    z2 = a.get("runner_up")
    z2 = 0.0 if z2 is None or z2 < 0.0 else z2
    return [1.0, z, min(max(z - z2, 0.0), GAP_CAP)]


def fit(rows, labels, lam=LAMBDA, iterations=50):
    """L2-regularised logistic regression (intercept not penalised) by Newton's method."""
    w = [0.0] * len(rows[0])
    for _ in range(iterations):
        grad = [0.0] * len(w)
        hess = [[0.0] * len(w) for _ in w]
        for x, y in zip(rows, labels):
            p = 1.0 / (1.0 + math.exp(-sum(a * b for a, b in zip(w, x))))
            for i in range(len(w)):
                grad[i] += (p - y) * x[i]
                for j in range(len(w)):
                    hess[i][j] += p * (1.0 - p) * x[i] * x[j]
        for i in range(1, len(w)):
            grad[i] += lam * w[i]
            hess[i][i] += lam
        step = solve(hess, grad)
        w = [a - b for a, b in zip(w, step)]
        if max(abs(s) for s in step) < 1e-10:
            break
    return w


def solve(a, b):
    """Gaussian elimination with partial pivoting (a small dense system)."""
    n = len(b)
    m = [row[:] + [b[i]] for i, row in enumerate(a)]
    for c in range(n):
        p = max(range(c, n), key=lambda r: abs(m[r][c]))
        m[c], m[p] = m[p], m[c]
        for r in range(n):
            if r != c and m[c][c] != 0.0:
                f = m[r][c] / m[c][c]
                m[r] = [x - f * y for x, y in zip(m[r], m[c])]
    return [m[i][n] / m[i][i] if m[i][i] != 0.0 else 0.0 for i in range(n)]


def predict(w, x):
    return 1.0 / (1.0 + math.exp(-sum(a * b for a, b in zip(w, x))))


def report(answers, w):
    lines = [f"Coefficients: bias {w[0]:.3f}, margin {w[1]:.3f}, lead {w[2]:.3f} "
             f"(λ = {LAMBDA}, {len(answers)} answers, "
             f"{sum(is_right(a) for a in answers)} right)\n",
             "| scenes | outliers | seed | answer | rotation error | z | z₂ | existence | time |",
             "|---|---:|---:|---|---:|---:|---:|---:|---:|"]
    for a in answers:
        p = predict(w, features(a))
        lines.append(
            f"| {a['scenes']} | {100 * a['level']:.0f} % | {a['seed']} | "
            f"{'right' if is_right(a) else 'wrong'} | {a['rotation_deg']:.1f}° | "
            f"{a.get('margin', 0.0):.1f} | {a.get('runner_up', float('nan')):.1f} | "
            f"{p:.2f} | {a['seconds']:.1f} s |")
    lines += ["", "| fitted existence | answers | right | right share |", "|---|---:|---:|---:|"]
    bins = [(0.0, 0.1), (0.1, 0.3), (0.3, 0.5), (0.5, 0.7), (0.7, 0.9), (0.9, 1.01)]
    for lo, hi in bins:
        inside = [a for a in answers if lo <= predict(w, features(a)) < hi]
        right = sum(is_right(a) for a in inside)
        share = f"{right / len(inside):.2f}" if inside else "–"
        lines.append(f"| {lo:.1f}–{min(hi, 1.0):.1f} | {len(inside)} | {right} | {share} |")
    return "\n".join(lines) + "\n"


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--seeds", type=int, default=4)
    ap.add_argument("--first-seed", type=int, default=100)
    ap.add_argument("--out")
    ap.add_argument("--runs", help="answers of an earlier run (JSON lines) to refit")
    ap.add_argument("--save-runs", help="write the answers here (JSON lines)")
    ap.add_argument("--sensors-only", action="store_true",
                    help="only the scenes whose points carry sensor origins (partial views)")
    ap.add_argument("--bench-args", default="",
                    help="more registration_bench flags, e.g. '--accept 0.5'")
    args = ap.parse_args()
    if args.runs:
        with open(args.runs) as f:
            answers = [json.loads(line) for line in f if line.strip()]
    else:
        if not os.path.exists(BENCH):
            subprocess.run(["cargo", "build", "--release", "--example", "registration_bench"],
                           cwd=ROOT, check=True)
        answers = run_scenes(args.seeds, args.first_seed, args.bench_args.split(),
                             args.sensors_only)
    if args.save_runs:
        with open(args.save_runs, "w") as f:
            for a in answers:
                f.write(json.dumps(a) + "\n")
    w = fit([features(a) for a in answers], [1.0 if is_right(a) else 0.0 for a in answers])
    text = report(answers, w)
    print(text)
    if args.out:
        with open(args.out, "w") as f:
            f.write(text)


if __name__ == "__main__":
    main()
