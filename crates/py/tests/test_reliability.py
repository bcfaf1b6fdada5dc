"""Regression tests of the reliability issue (#19) on the Python side: every oversized
request raises before it allocates, thread counts are bounded, Ctrl-C stops a fit."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import textwrap
import time

import numpy as np
import pytest

import primfit


def plane(n: int = 300) -> np.ndarray:
    rng = np.random.default_rng(0)
    return np.column_stack([rng.random(n), rng.random(n), np.zeros(n)])


@pytest.mark.parametrize("n", [2**40, 2**62])
def test_chamfer_problem_with_an_absurd_candidate_count_raises(n):
    rng = np.random.default_rng(0)
    cloud, samples = rng.random((50, 3)), rng.random((20, 3))
    owner = np.arange(20) % 4
    with pytest.raises(ValueError, match="n must be at most the 20 samples"):
        primfit.ChamferProblem(cloud, samples, owner, n)


def test_chamfer_problem_over_the_memory_budget_raises_before_allocating():
    # 2e6 points x 5e4 candidates with beta = inf: some 10 TB of coefficients.
    cloud = np.zeros((2_000_000, 3))
    cloud[:, 0] = np.arange(2_000_000)
    samples = np.column_stack([np.arange(50_000.0), np.zeros(50_000), np.zeros(50_000)])
    owner = np.arange(50_000)
    with pytest.raises(ValueError, match="too large: the coefficients of 2000000 points"):
        primfit.ChamferProblem(cloud, samples, owner, beta="inf")


def _misaligned(a: np.ndarray) -> np.ndarray:
    """A copy of ``a`` whose data starts one byte into a buffer: C-ordered, not aligned."""
    buf = np.zeros(a.nbytes + 1, dtype=np.uint8)
    out = np.frombuffer(buf.data, dtype=a.dtype, count=a.size, offset=1).reshape(a.shape)
    out[...] = a
    return out


def test_misaligned_arrays_are_read_like_aligned_ones():
    rng = np.random.default_rng(0)
    cloud, samples = rng.random((50, 3)), rng.random((20, 3))
    owner, p = np.arange(20) % 4, np.full(4, 0.5)
    odd = [_misaligned(x) for x in (cloud, samples, owner, p)]
    assert not any(x.flags.aligned for x in odd)
    want = primfit.probabilistic_chamfer(cloud, samples, owner, p, cap=0.25)
    got = primfit.probabilistic_chamfer(*odd, cap=0.25)
    assert got[:2] == want[:2]
    np.testing.assert_array_equal(got[2], want[2])


def test_synthetic_scenes_refuse_more_points_than_memory_holds():
    with pytest.raises(ValueError, match="inliers"):
        primfit.synth.registration(inliers=10**12)
    with pytest.raises(ValueError, match="outliers"):
        primfit.synth.registration(outliers=10**15)


def test_candidates_of_a_fine_lattice_raise_instead_of_aborting():
    with pytest.raises(ValueError, match="spacing"):
        primfit.candidates(plane(), types="square", size=1.0, spacing=0.02)
    with pytest.raises(ValueError, match="spacing"):
        primfit.candidates(plane(), types="square", size=1.0, spacing=0.02).problem()


def test_fit_over_the_work_budget_names_it():
    with pytest.raises(ValueError, match="work_budget"):
        primfit.fit(plane(2000), types="square", size=0.5, beta="inf", work_budget=1.0)
    with pytest.raises(ValueError, match="work_budget must be positive"):
        primfit.fit(plane(2000), types="square", work_budget=-1.0)


def run_python(code: str, env: dict[str, str] | None = None, **kw) -> subprocess.Popen:
    return subprocess.Popen(
        [sys.executable, "-c", textwrap.dedent(code)],
        env={**os.environ, **(env or {})},
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        **kw,
    )


def test_thread_count_from_the_environment_is_bounded():
    child = run_python(
        """
        import numpy as np, primfit
        try:
            primfit.fit(np.random.default_rng(0).random((100, 3)), types="square")
        except ValueError as e:
            print("refused:", e)
        """,
        env={"RAYON_NUM_THREADS": "100000"},
    )
    out, err = child.communicate(timeout=120)
    assert "refused: RAYON_NUM_THREADS must be between 1 and" in out, out + err


def test_ctrl_c_stops_a_running_fit_with_keyboard_interrupt():
    # A fit that runs for minutes (a fine lattice with a raised work budget); SIGINT
    # once the child says it started.
    child = run_python(
        """
        import sys, numpy as np, primfit
        cloud = primfit.synth.hallway(seed=0)[0]
        print("started", flush=True)
        try:
            primfit.fit(cloud, types="square", spacing=0.1, beta=256, work_budget=1e12)
            print("finished")
        except KeyboardInterrupt:
            print("interrupted")
        """
    )
    assert child.stdout is not None
    assert child.stdout.readline().strip() == "started"
    time.sleep(2.0)  # inside the Rust fit by now
    child.send_signal(signal.SIGINT)
    out, err = child.communicate(timeout=120)
    assert "interrupted" in out, out + err
