"""Shared helpers of the primfit Python tests.

PRIMFIT_REQUIRE_ALL=1 (set by CI through scripts/test.sh) turns every "optional
dependency missing" skip into a failure, so a CI run cannot pass by skipping.
"""

from __future__ import annotations

import importlib
import os
from types import ModuleType

import numpy as np
import pytest

REQUIRE_ALL = os.environ.get("PRIMFIT_REQUIRE_ALL") == "1"


def require(module: str) -> ModuleType:
    """Imports an optional module: skips the test without it, or fails under
    PRIMFIT_REQUIRE_ALL=1."""
    try:
        return importlib.import_module(module)
    except ImportError as e:
        if REQUIRE_ALL:
            pytest.fail(f"{module} is required when PRIMFIT_REQUIRE_ALL=1: {e}")
        pytest.skip(f"{module} is not installed")


def unavailable(reason: str) -> None:
    """Skips (or, under PRIMFIT_REQUIRE_ALL=1, fails) a test whose prerequisite is missing."""
    if REQUIRE_ALL:
        pytest.fail(f"{reason} (PRIMFIT_REQUIRE_ALL=1)")
    pytest.skip(reason)


def random_problem(seed: int, j: int = 12, n: int = 5, per: int = 4):
    """A small random problem: cloud (j, 3), samples (n·per, 3) with owners, p (n,)."""
    rng = np.random.default_rng(seed)
    cloud = rng.random((j, 3))
    owner = rng.permutation(np.repeat(np.arange(n), per))
    samples = rng.random((len(owner), 3))
    p = rng.uniform(0.05, 0.95, n)
    return cloud, samples, owner, p


def reference_chamfer(cloud, samples, owner, p, *, model="existence", alpha=None, beta=None, cap=0.0):
    """DESIGN §2 by brute force (NumPy, loops): ``(primitive_term, point_term)``.

    Entries for a point y: the β candidates whose nearest sample is closest (ties: lower
    candidate index); per kept candidate its nearest sample (``existence``) or its α
    nearest samples (``independent``, ties: lower sample index); all entries sorted by
    distance; ``E_y = Σ_k d_k q_k Π_{l<k}(1 − q_l) + Π_all(1 − q_l) · cap``.
    """
    cloud, samples, p = (np.asarray(a, dtype=np.float64) for a in (cloud, samples, p))
    owner = np.asarray(owner)
    n = len(p)
    d2 = ((samples[:, None, :] - cloud[None, :, :]) ** 2).sum(axis=-1)  # (K, J)
    g = np.array([d2[owner == i].min(axis=1).sum() for i in range(n)])
    primitive = float(g @ p)
    point = 0.0
    for j in range(len(cloud)):
        per_candidate = []
        for i in range(n):
            ks = np.flatnonzero(owner == i)
            order = sorted(ks, key=lambda k: (d2[k, j], k))
            per_candidate.append([d2[k, j] for k in order])
        kept = sorted(range(n), key=lambda i: (per_candidate[i][0], i))[: beta or n]
        entries = []
        for i in kept:
            ds = per_candidate[i][:1] if model == "existence" else per_candidate[i][: alpha or None]
            entries += [(d, i) for d in ds]
        entries.sort()
        value, survive = 0.0, 1.0
        for d, i in entries:
            value += d * p[i] * survive
            survive *= 1.0 - p[i]
        point += value + survive * cap
    return primitive, point
