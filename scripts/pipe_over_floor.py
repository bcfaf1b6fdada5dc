#!/usr/bin/env python3
"""A pipe over a floor, for checking `primfit fit` on thin tubes beside quiet planes.

A 4 x 3 m floor (3 cm spacing) and, 1 m above it, a pipe of radius --radius (1.2 cm
spacing): a 2 m run, a bend of --bend degrees (bend radius max(0.3 m, 3 radii)) and a
1.5 m run; --bend 0 gives the straight run alone. Gaussian noise --noise on every
coordinate, written as ascii PLY (docs/compact.md, "Strips of a thin tube").

    python3 scripts/pipe_over_floor.py pipe.ply --bend 90 --noise 0.002
    primfit fit pipe.ply

Needs numpy.
"""
import argparse

import numpy as np

import ascii_ply


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("output")
    ap.add_argument("--bend", type=float, default=90.0, help="bend angle, degrees")
    ap.add_argument("--radius", type=float, default=0.06, help="pipe radius, m")
    ap.add_argument("--noise", type=float, default=0.002, help="Gaussian σ, m")
    ap.add_argument("--no-floor", action="store_true")
    ap.add_argument("--seed", type=int, default=7)
    args = ap.parse_args()
    rng = np.random.default_rng(args.seed)
    r, pipe_spacing, floor_spacing = args.radius, 0.012, 0.03
    big = max(0.3, 3 * r)
    parts = []

    def tube(base, axis, length):
        axis = np.asarray(axis, float) / np.linalg.norm(axis)
        t = np.cross(axis, [0, 0, 1.0])
        t /= np.linalg.norm(t)
        b = np.cross(axis, t)
        n = int(2 * np.pi * r * length / pipe_spacing**2)
        th, z = rng.random(n) * 2 * np.pi, rng.random(n) * length
        ring = np.outer(np.cos(th), t) + np.outer(np.sin(th), b)
        parts.append(np.asarray(base) + np.outer(z, axis) + r * ring)

    tube([0, 0, 1], [1, 0, 0], 2.0)
    angle = np.radians(args.bend)
    if angle > 0:
        # The bend: its centre line c + big (cos a u + sin a v), a in [0, angle].
        c, u, v = np.array([2, big, 1.0]), np.array([0, -1.0, 0]), np.array([1.0, 0, 0])
        n = int(angle * big * 2 * np.pi * r / pipe_spacing**2)
        a, phi = rng.random(n) * angle, rng.random(n) * 2 * np.pi
        radial = np.outer(np.cos(a), u) + np.outer(np.sin(a), v)
        w = np.cross(u, v)
        parts.append(c + big * radial + r * (np.cos(phi)[:, None] * radial + np.outer(np.sin(phi), w)))
        end = c + big * (np.cos(angle) * u + np.sin(angle) * v)
        tube(end, [np.cos(angle), np.sin(angle), 0], 1.5)
    if not args.no_floor:
        n = int(4 * 3 / floor_spacing**2)
        a = rng.random((n, 2))
        parts.append(np.array([-0.5, -1, 0]) + a[:, :1] * [4, 0, 0] + a[:, 1:] * [0, 3, 0])
    p = np.vstack(parts)
    p += rng.normal(scale=args.noise, size=p.shape)
    ascii_ply.write(args.output, p)
    print(f"{args.output}: {len(p)} points")


if __name__ == "__main__":
    main()
