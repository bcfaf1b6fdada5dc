"""The GIL is released during long calls, and calls work in a forked child."""

from __future__ import annotations

import os
import sys
import threading
import time
import warnings

import numpy as np
import pytest

import primfit


def big_problem():
    rng = np.random.default_rng(0)
    n, per = 400, 20
    cloud = rng.random((20000, 3))
    owner = np.repeat(np.arange(n), per)
    samples = rng.random((n * per, 3))
    return primfit.ChamferProblem(cloud, samples, owner, cap=0.1, beta=16)


def long_batch(problem) -> np.ndarray:
    """A batch whose evaluation takes a while (sized from one timed call)."""
    p = np.full((1, problem.n_candidates), 0.5)
    t = time.perf_counter()
    problem.evaluate_batch(p)
    one = max(time.perf_counter() - t, 1e-4)
    return np.full((int(np.clip(0.3 / one, 4, 5000)), problem.n_candidates), 0.5)


@pytest.fixture
def no_forced_switches():
    """A switch interval far longer than any call here: CPython then never takes the GIL
    from a running thread, so another thread runs Python only when the GIL is released
    (blocking calls, sleeps, or an extension's detach). Timestamp order alone then shows
    whether a call released the GIL."""
    old = sys.getswitchinterval()
    sys.setswitchinterval(100.0)
    yield
    sys.setswitchinterval(old)


def test_gil_is_released_during_evaluation(no_forced_switches):
    """While one thread is inside Rust, the main thread runs Python code (ticks)."""
    problem = big_problem()
    P = long_batch(problem)
    stamps: dict[str, float] = {}
    done = threading.Event()

    def worker():
        stamps["start"] = time.perf_counter()
        problem.evaluate_batch(P)
        stamps["end"] = time.perf_counter()
        done.set()

    ticks = []
    thread = threading.Thread(target=worker)
    thread.start()
    while not done.is_set():
        ticks.append(time.perf_counter())
        time.sleep(0.001)  # lets the worker take the GIL to start and to return
    thread.join()
    assert any(stamps["start"] < t < stamps["end"] for t in ticks), "no Python ran while the worker was in Rust"


def test_two_threads_evaluate_concurrently(no_forced_switches):
    """Two threads inside Rust at once: each call starts before the other ends, and the
    results equal those of sequential calls."""
    problem = big_problem()
    P = long_batch(problem)
    out: dict[int, tuple] = {}
    barrier = threading.Barrier(2)

    def worker(k):
        barrier.wait()
        start = time.perf_counter()
        totals, _ = problem.evaluate_batch(P)
        out[k] = (start, time.perf_counter(), totals)

    threads = [threading.Thread(target=worker, args=(k,)) for k in range(2)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    (s0, e0, r0), (s1, e1, r1) = out[0], out[1]
    assert s0 < e1 and s1 < e0, "the two calls ran one after the other"
    np.testing.assert_array_equal(r0, r1)


@pytest.mark.skipif(not hasattr(os, "fork"), reason="needs os.fork")
def test_calls_in_a_forked_child_do_not_hang():
    """rayon's pool does not survive fork(); the bindings use a per-process pool."""
    rng = np.random.default_rng(1)
    cloud, samples = rng.random((5000, 3)), rng.random((2000, 3))
    owner = np.arange(2000) % 100
    p = np.full(100, 0.5)
    expected = primfit.probabilistic_chamfer(cloud, samples, owner, p, cap=0.1)  # starts the pool here

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DeprecationWarning)  # fork with threads (3.12+)
        pid = os.fork()
    if pid == 0:  # child: must leave through os._exit, whatever happens
        code = 1
        try:
            got = primfit.probabilistic_chamfer(cloud, samples, owner, p, cap=0.1)
            problem = primfit.ChamferProblem(cloud, samples, owner, cap=0.1)
            problem.evaluate_batch(np.full((8, 100), 0.5))
            code = 0 if got[:2] == expected[:2] else 2
        finally:
            os._exit(code)

    deadline = time.monotonic() + 60.0
    while time.monotonic() < deadline:
        done, status = os.waitpid(pid, os.WNOHANG)
        if done:
            assert os.waitstatus_to_exitcode(status) == 0
            break
        time.sleep(0.05)
    else:
        os.kill(pid, 9)
        os.waitpid(pid, 0)
        pytest.fail("the forked child hung in a primfit call")
    # The parent's pool still works.
    assert primfit.probabilistic_chamfer(cloud, samples, owner, p, cap=0.1)[:2] == expected[:2]
