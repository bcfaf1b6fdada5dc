#!/usr/bin/env python3
"""A room with thin pipes, for checking `primfit fit` beyond the bundled examples.

A 6 x 5 m room (floor, three walls), a 25 cm column, a table on four 3 cm legs, and
8 cm pipes 30 cm off a wall: a 2 m run, a 45-degree bend (bend radius 0.4 m) and a
0.6 m run; a 2.4 m run with a branch down to the floor (a tee). Gaussian noise of 5 mm,
176 600 points, written as ascii PLY (docs/compact.md, "A room with thin pipes").

    python3 scripts/room_with_pipes.py room.ply [--seed 0]
    primfit fit room.ply

Needs numpy.
"""
import argparse

import numpy as np

import ascii_ply


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("output")
    ap.add_argument("--seed", type=int, default=0)
    args = ap.parse_args()
    rng = np.random.default_rng(args.seed)
    parts = []

    def rect(origin, u, v, n):
        a = rng.random((n, 2))
        parts.append(np.asarray(origin) + a[:, :1] * np.asarray(u) + a[:, 1:] * np.asarray(v))

    def tube(base, axis, r, length, n):
        axis = np.asarray(axis, float) / np.linalg.norm(axis)
        t = np.cross(axis, [0, 0, 1.0] if abs(axis[2]) < 0.9 else [1.0, 0, 0])
        t /= np.linalg.norm(t)
        b = np.cross(axis, t)
        th, z = rng.random(n) * 2 * np.pi, rng.random(n) * length
        ring = np.outer(np.cos(th), t) + np.outer(np.sin(th), b)
        parts.append(np.asarray(base) + np.outer(z, axis) + r * ring)

    def bend(centre, big, r, a0, a1, n, e1, e2):
        phi, th = a0 + rng.random(n) * (a1 - a0), rng.random(n) * 2 * np.pi
        out = np.outer(np.cos(phi), e1) + np.outer(np.sin(phi), e2)
        e3 = np.cross(e1, e2)
        parts.append(centre + (big + r * np.cos(th))[:, None] * out
                     + (r * np.sin(th))[:, None] * e3)

    rect([0, 0, 0], [6, 0, 0], [0, 5, 0], 60000)  # floor
    rect([0, 0, 0], [6, 0, 0], [0, 0, 3], 30000)  # wall y = 0
    rect([0, 0, 0], [0, 5, 0], [0, 0, 3], 25000)  # wall x = 0
    rect([6, 0, 0], [0, 5, 0], [0, 0, 3], 25000)  # wall x = 6
    tube([3, 3, 0], [0, 0, 1], 0.25, 3.0, 12000)  # column
    rect([1, 2, 0.75], [1.6, 0, 0], [0, 0.8, 0], 6000)  # table top
    for x, y in [(1.05, 2.05), (2.55, 2.05), (1.05, 2.75), (2.55, 2.75)]:
        tube([x, y, 0], [0, 0, 1], 0.03, 0.75, 400)  # legs
    r, y0, z0, big = 0.08, 0.3, 2.2, 0.4
    tube([0, y0, z0], [1, 0, 0], r, 2.0, 5000)  # run along the wall
    centre = np.array([2.0, y0, z0 + big])
    x, z = np.array([1.0, 0, 0]), np.array([0, 0, 1.0])
    bend(centre, big, r, -np.pi / 2, -np.pi / 4, 1200, x, z)  # 45-degree bend
    end = centre + big * np.array([np.cos(-np.pi / 4), 0, np.sin(-np.pi / 4)])
    tube(end, [1, 0, 1], r, 0.6, 1800)  # run at 45 degrees
    tube([3.5, y0, 1.2], [1, 0, 0], r, 2.4, 6000)  # run of the tee
    tube([4.7, y0, 0.0], [0, 0, 1], r, 1.2 - r, 3000)  # its branch to the floor
    points = np.vstack(parts)
    points += rng.normal(0, 0.005, points.shape)
    ascii_ply.write(args.output, points)
    print(f"wrote {args.output}: {len(points)} points")


if __name__ == "__main__":
    main()
