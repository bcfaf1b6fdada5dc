"""Bad input raises a Python exception with a clear message, never crashes."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import random_problem

import primfit
from primfit import _primfit


@pytest.fixture
def problem_args():
    return random_problem(0)


def chamfer(cloud, samples, owner, p, **kw):
    return primfit.probabilistic_chamfer(cloud, samples, owner, p, **kw)


@pytest.mark.parametrize(
    ("which", "bad", "match"),
    [
        ("cloud", np.zeros((4, 2)), r"cloud must have shape \(M, 3\)"),
        ("cloud", np.zeros(12), r"cloud must have 2 dimension"),
        ("cloud", np.zeros((2, 2, 3)), r"cloud must have 2 dimension"),
        ("samples", np.zeros((20, 4)), r"samples must have shape \(M, 3\)"),
        ("cloud", np.zeros((0, 3)), r"cloud is empty"),
        ("samples", np.zeros((0, 3)), r"samples is empty"),
    ],
)
def test_wrong_shapes_and_empty_arrays(problem_args, which, bad, match):
    cloud, samples, owner, p = problem_args
    args = {"cloud": cloud, "samples": samples}
    args[which] = bad
    with pytest.raises(ValueError, match=match):
        chamfer(args["cloud"], args["samples"], owner, p)


def test_wrong_lengths(problem_args):
    cloud, samples, owner, p = problem_args
    with pytest.raises(ValueError, match="owners"):
        chamfer(cloud, samples, owner[:-1], p)
    problem = primfit.ChamferProblem(cloud, samples, owner)
    with pytest.raises(ValueError, match="length N = 5"):
        problem.evaluate(p[:-1])
    with pytest.raises(ValueError, match="1 dimension"):
        problem.evaluate(p[None, :])
    with pytest.raises(ValueError, match=r"shape \(B, N\) with N = 5"):
        problem.evaluate_batch(np.zeros((2, 4)))
    with pytest.raises(ValueError, match="2 dimension"):
        problem.evaluate_batch(p)
    with pytest.raises(ValueError, match="at least one candidate"):
        chamfer(cloud, samples, owner, np.zeros(0))


@pytest.mark.parametrize("bad", [np.nan, np.inf, -np.inf])
def test_non_finite_values(problem_args, bad):
    cloud, samples, owner, p = problem_args
    c = cloud.copy()
    c[3, 1] = bad
    with pytest.raises(ValueError, match="cloud contains NaN or infinite"):
        chamfer(c, samples, owner, p)
    s = samples.copy()
    s[0, 0] = bad
    with pytest.raises(ValueError, match="samples contains NaN or infinite"):
        chamfer(cloud, s, owner, p)
    q = p.copy()
    q[2] = bad
    with pytest.raises(ValueError, match="p contains NaN or infinite"):
        chamfer(cloud, samples, owner, q)
    problem = primfit.ChamferProblem(cloud, samples, owner)
    P = np.tile(p, (3, 1))
    P[1, 4] = bad
    with pytest.raises(ValueError, match=r"P\[1\]"):
        problem.evaluate_batch(P)


@pytest.mark.parametrize("bad", [-0.1, 1.5])
def test_probabilities_outside_unit_interval(problem_args, bad):
    cloud, samples, owner, p = problem_args
    q = p.copy()
    q[1] = bad
    with pytest.raises(ValueError, match=r"p\[1\] = .* is not a probability"):
        chamfer(cloud, samples, owner, q)


def test_owner_checks(problem_args):
    cloud, samples, owner, p = problem_args
    o = owner.copy()
    o[0] = 5  # N = len(p) = 5
    with pytest.raises(ValueError, match="owner.* is not a candidate index"):
        chamfer(cloud, samples, o, p)
    o[0] = -1
    with pytest.raises(ValueError, match="negative"):
        chamfer(cloud, samples, o, p)
    with pytest.raises(ValueError, match="candidate 5 has no samples"):
        chamfer(cloud, samples, owner, np.full(6, 0.5))
    with pytest.raises(TypeError, match="owner must be a numeric array"):
        chamfer(cloud, samples, owner.astype(float), p)
    with pytest.raises(ValueError, match="1 dimension"):
        chamfer(cloud, samples, owner[:, None], p)


@pytest.mark.parametrize(
    "bad",
    [
        np.array([["a", "b", "c"]] * 4),
        np.array([[1.0, 2.0, 3.0]] * 4, dtype=object),
        np.array([[True, False, True]] * 4),
        [[1.0, 2.0, 3.0], [4.0, 5.0]],  # ragged
    ],
    ids=["str", "object", "bool", "ragged"],
)
def test_non_numeric_arrays_are_rejected(problem_args, bad):
    cloud, samples, owner, p = problem_args
    with pytest.raises((TypeError, ValueError)):
        chamfer(bad, samples, owner, p)
    with pytest.raises((TypeError, ValueError)):
        primfit.ChamferProblem(cloud, samples, owner).evaluate(np.asarray(bad, dtype=object).ravel())


def test_object_and_string_arrays_raise_type_error(problem_args):
    cloud, samples, owner, p = problem_args
    with pytest.raises(TypeError, match="dtype object"):
        chamfer(cloud.astype(object), samples, owner, p)
    with pytest.raises(TypeError, match="dtype <U"):
        chamfer(cloud.astype(str), samples, owner, p)


@pytest.mark.parametrize(
    ("kw", "match"),
    [
        ({"model": "nearest"}, "unknown point model"),
        ({"alpha": 0}, "alpha must be at least 1"),
        ({"beta": -3}, "beta must be at least 1"),
        ({"beta": "many"}, "beta must be a positive integer or 'inf'"),
        ({"alpha": 2.5}, "alpha must be a positive integer"),
        ({"cap": -1.0}, "cap must be finite"),
        ({"cap": float("nan")}, "cap must be finite"),
        ({"weights": (1.0, -1.0)}, "point_weight"),
    ],
)
def test_bad_options(problem_args, kw, match):
    cloud, samples, owner, p = problem_args
    with pytest.raises(ValueError, match=match):
        chamfer(cloud, samples, owner, p, **kw)


def test_fit_errors():
    cloud = np.random.default_rng(0).random((200, 3))
    with pytest.raises(ValueError, match="cloud is empty"):
        primfit.fit(np.zeros((0, 3)))
    with pytest.raises(ValueError, match="cloud contains NaN"):
        primfit.fit(np.full((5, 3), np.nan))
    with pytest.raises(ValueError):
        primfit.fit(cloud, types=["blob"])
    with pytest.raises(ValueError, match="size"):
        primfit.fit(cloud, types="square", size=-1.0)  # (the compact model has no size)
    with pytest.raises(ValueError, match="mesh"):
        primfit.fit(cloud, types="mesh")
    with pytest.raises(ValueError, match="too large"):
        primfit.fit(cloud, types="square", size=0.5, memory_budget=10)
    with pytest.raises(TypeError):
        primfit.fit(cloud, sizes=1.0)  # unknown option


def test_file_errors(tmp_path):
    with pytest.raises(OSError):
        primfit.read_ply(tmp_path / "missing.ply")
    junk = tmp_path / "junk.ply"
    junk.write_bytes(b"this is not a ply file\n")
    with pytest.raises(ValueError, match="junk.ply"):
        primfit.read_ply(junk)
    with pytest.raises(OSError):
        primfit.write_ply(tmp_path / "no" / "such" / "dir.ply", np.zeros((1, 3)))
    with pytest.raises(ValueError, match="colors must be in 0..255"):
        primfit.write_ply(tmp_path / "c.ply", np.zeros((1, 3)), colors=[[0, 0, 300]])
    with pytest.raises(ValueError, match=r"normals must have shape \(1, 3\)"):
        primfit.write_ply(tmp_path / "n.ply", np.zeros((1, 3)), normals=np.zeros((2, 3)))


def test_extension_errors_do_not_crash():
    # Straight into the extension: wrong dtypes and dimensions are Python exceptions.
    with pytest.raises(TypeError):
        _primfit.ChamferProblem(np.zeros((3, 3), dtype=np.int64), np.zeros((3, 3)), np.zeros(3, dtype=np.int64))
    with pytest.raises(TypeError):
        _primfit.ChamferProblem(np.zeros(9), np.zeros((3, 3)), np.zeros(3, dtype=np.int64))
    with pytest.raises(TypeError):
        _primfit.fit(np.zeros((3, 3)), None)
