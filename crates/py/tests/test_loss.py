"""The probabilistic chamfer: values against a brute-force NumPy reference, gradients
against finite differences, batches, input handling."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import random_problem, reference_chamfer

import primfit
from primfit import _primfit

MODELS = ["existence", "independent"]


@pytest.mark.parametrize("model", MODELS)
@pytest.mark.parametrize("seed", range(4))
def test_exact_loss_matches_brute_force(model, seed):
    cloud, samples, owner, p = random_problem(seed)
    cap = 0.3
    prim, point, _ = primfit.probabilistic_chamfer(cloud, samples, owner, p, model=model, cap=cap)
    ref_prim, ref_point = reference_chamfer(cloud, samples, owner, p, model=model, cap=cap)
    assert prim == pytest.approx(ref_prim, rel=1e-12)
    assert point == pytest.approx(ref_point, rel=1e-12)


@pytest.mark.parametrize("model", MODELS)
@pytest.mark.parametrize(("alpha", "beta"), [(1, 1), (2, 3), (3, 2)])
def test_approximations_match_brute_force(model, alpha, beta):
    cloud, samples, owner, p = random_problem(11, j=15, n=6, per=5)
    got = primfit.probabilistic_chamfer(cloud, samples, owner, p, model=model, alpha=alpha, beta=beta, cap=0.2)
    ref = reference_chamfer(cloud, samples, owner, p, model=model, alpha=alpha, beta=beta, cap=0.2)
    assert got[:2] == pytest.approx(ref, rel=1e-12)


def test_unlimited_spellings_are_exact():
    cloud, samples, owner, p = random_problem(3)
    exact = primfit.probabilistic_chamfer(cloud, samples, owner, p, model="independent", cap=0.1)
    for spelling in ("inf", float("inf")):
        got = primfit.probabilistic_chamfer(
            cloud, samples, owner, p, model="independent", alpha=spelling, beta=spelling, cap=0.1
        )
        assert got[:2] == exact[:2]


@pytest.mark.parametrize("model", MODELS)
def test_gradient_matches_finite_differences(model):
    cloud, samples, owner, p = random_problem(5, j=20, n=7)
    weights = (0.7, 1.3)
    problem = primfit.ChamferProblem(cloud, samples, owner, model=model, cap=0.25, weights=weights)

    def total(q):
        prim, point, _ = problem.evaluate(q)
        return weights[0] * prim + weights[1] * point

    _, _, grad = problem.evaluate(p)
    h = 1e-6
    for i in range(len(p)):
        e = np.zeros_like(p)
        e[i] = h
        fd = (total(p + e) - total(p - e)) / (2 * h)
        assert grad[i] == pytest.approx(fd, rel=1e-6, abs=1e-8)


def test_primitive_term_is_linear_in_g():
    cloud, samples, owner, p = random_problem(6)
    problem = primfit.ChamferProblem(cloud, samples, owner)
    prim, _, _ = problem.evaluate(p)
    assert prim == pytest.approx(problem.g @ p, rel=1e-14)


def test_point_term_at_binary_scenes_is_the_binary_chamfer():
    cloud, samples, owner, _ = random_problem(8)
    exists = np.array([1, 0, 1, 0, 0], dtype=float)
    _, point, _ = primfit.probabilistic_chamfer(cloud, samples, owner, exists, cap=10.0)
    kept = samples[np.isin(owner, np.flatnonzero(exists))]
    d2 = ((cloud[:, None] - kept[None]) ** 2).sum(-1).min(axis=1)
    assert point == pytest.approx(d2.sum(), rel=1e-12)
    _, point0, _ = primfit.probabilistic_chamfer(cloud, samples, owner, np.zeros(5), cap=10.0)
    assert point0 == pytest.approx(10.0 * len(cloud))


def test_problem_reuse_equals_one_shot_and_batch_equals_rows():
    cloud, samples, owner, _ = random_problem(9, n=6)
    problem = primfit.ChamferProblem(cloud, samples, owner, cap=0.2, weights=(2.0, 0.5))
    assert (problem.n_candidates, problem.n_points) == (6, len(cloud))
    assert problem.weights == (2.0, 0.5)
    P = np.random.default_rng(0).random((5, 6))
    totals, grads = problem.evaluate_batch(P)
    assert totals.shape == (5,) and grads.shape == (5, 6)
    for b, row in enumerate(P):
        prim, point, grad = primfit.probabilistic_chamfer(
            cloud, samples, owner, row, cap=0.2, weights=(2.0, 0.5)
        )
        assert totals[b] == pytest.approx(2.0 * prim + 0.5 * point, rel=1e-13)
        np.testing.assert_allclose(grads[b], grad, rtol=1e-13)
    # Fortran-ordered batch: same answer.
    totals_f, grads_f = problem.evaluate_batch(np.asfortranarray(P))
    np.testing.assert_array_equal(totals_f, totals)
    np.testing.assert_array_equal(grads_f, grads)
    empty_totals, empty_grads = problem.evaluate_batch(np.zeros((0, 6)))
    assert empty_totals.shape == (0,) and empty_grads.shape == (0, 6)


def test_results_are_float64_arrays_handed_over_without_copies():
    cloud, samples, owner, p = random_problem(1)
    _, _, grad = primfit.probabilistic_chamfer(cloud, samples, owner, p)
    assert grad.dtype == np.float64 and grad.shape == p.shape
    # The Rust allocation is handed to numpy (no copy): numpy does not own the data.
    assert not grad.flags.owndata
    assert type(grad.base).__name__ == "PySliceContainer"


def test_fortran_order_and_strided_inputs_give_the_same_answer():
    cloud, samples, owner, p = random_problem(2, j=30, n=6)
    expected = primfit.probabilistic_chamfer(cloud, samples, owner, p, cap=0.2)
    # Through the facade (which copies to C order) ...
    got = primfit.probabilistic_chamfer(np.asfortranarray(cloud), np.asfortranarray(samples), owner, p, cap=0.2)
    assert got[:2] == expected[:2]
    np.testing.assert_array_equal(got[2], expected[2])
    # ... and straight into the extension, which must read strides, not raw memory.
    raw = _primfit.ChamferProblem(
        np.asfortranarray(cloud), np.asfortranarray(samples), owner.astype(np.int64), cap=0.2
    ).evaluate(np.ascontiguousarray(p))
    assert raw[:2] == expected[:2]
    wide = np.zeros((len(cloud), 6))
    wide[:, ::2] = cloud  # a non-contiguous (strided) view
    raw = _primfit.ChamferProblem(wide[:, ::2], samples, owner.astype(np.int64), cap=0.2).evaluate(p)
    assert raw[:2] == expected[:2]
    pp = np.zeros(2 * len(p))
    pp[::2] = p
    raw = _primfit.ChamferProblem(cloud, samples, owner.astype(np.int64), cap=0.2).evaluate(pp[::2])
    assert raw[:2] == expected[:2]


def test_float32_and_list_inputs_are_coerced():
    cloud, samples, owner, p = random_problem(4)
    c32, s32, p32 = (a.astype(np.float32) for a in (cloud, samples, p))
    expected = primfit.probabilistic_chamfer(c32.astype(float), s32.astype(float), owner, p32.astype(float))
    got = primfit.probabilistic_chamfer(c32, s32, owner.astype(np.int32), p32)
    assert got[:2] == expected[:2]
    got = primfit.probabilistic_chamfer(c32.tolist(), s32.tolist(), owner.tolist(), p32.tolist())
    assert got[:2] == expected[:2]


def test_extension_rejects_float32_with_type_error():
    cloud, samples, owner, _ = random_problem(4)
    with pytest.raises(TypeError):
        _primfit.ChamferProblem(cloud.astype(np.float32), samples, owner.astype(np.int64))


def test_repr_mentions_sizes():
    cloud, samples, owner, _ = random_problem(4)
    text = repr(primfit.ChamferProblem(cloud, samples, owner, cap=0.5))
    assert "candidates=5" in text and "existence" in text


# --- solving -------------------------------------------------------------------------


def _clusters(seed: int):
    """Three point clusters far apart; candidates 0, 2, 4 sit on them, 1 and 3 on empty
    space (a problem whose binary minimum is {0, 2, 4}, checked by brute force)."""
    rng = np.random.default_rng(seed)
    centres = np.array([[0, 0, 0], [5, 0, 0], [10, 0, 0], [15, 0, 0], [20, 0, 0]], float)
    cloud = np.concatenate([centres[k] + 0.05 * rng.standard_normal((20, 3)) for k in (0, 2, 4)])
    samples = np.concatenate([centres[k] + 0.05 * rng.standard_normal((6, 3)) for k in range(5)])
    owner = np.repeat(np.arange(5), 6)
    return primfit.ChamferProblem(cloud, samples, owner, cap=1.0)


def _brute_force_minimum(problem) -> np.ndarray:
    best = min(range(32), key=lambda m: _binary_total(problem, m))
    return (best >> np.arange(5)) & 1 == 1


def _binary_total(problem, mask: int) -> float:
    p = ((mask >> np.arange(5)) & 1).astype(float)
    prim, point, _ = problem.evaluate(p)
    w = problem.weights
    return w[0] * prim + w[1] * point


def test_solve_finds_the_brute_force_minimum_from_several_starts():
    problem = _clusters(0)
    truth = _brute_force_minimum(problem)
    assert truth.tolist() == [True, False, True, False, True]
    for start in (0.5, 1.0, np.array([0.1, 0.9, 0.2, 0.8, 0.3])):
        s = problem.solve(start)
        assert s.exists.tolist() == truth.tolist(), start
        assert s.binary == pytest.approx(_binary_total(problem, 0b10101))
        assert len(s.history) == s.iterations + 1 and s.stop in ("gradient", "decrease", "iterations", "line_search")


def test_a_warm_start_at_the_answer_needs_no_iterations():
    problem = _clusters(1)
    cold = problem.solve()
    warm = problem.solve(cold.exists.astype(float))
    assert cold.iterations > 0 and warm.iterations == 0
    assert warm.exists.tolist() == cold.exists.tolist()


def test_solve_rejects_a_bad_start():
    problem = _clusters(2)
    with pytest.raises(ValueError, match="length N = 5"):
        problem.solve(np.full(4, 0.5))
    with pytest.raises(ValueError, match="not a probability"):
        problem.solve(np.array([0.5, 0.5, 1.5, 0.5, 0.5]))
    with pytest.raises(ValueError, match="finite|NaN"):
        problem.solve(np.array([0.5, np.nan, 0.5, 0.5, 0.5]))
