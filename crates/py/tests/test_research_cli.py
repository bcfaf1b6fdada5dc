"""The research harness runs as ``python -m primfit.research.<module>`` (its documented commands)."""

from __future__ import annotations

import subprocess
import sys

from conftest import require


def _help(module: str) -> str:
    """``python -m module --help`` in a fresh interpreter; fails unless it exits 0."""
    done = subprocess.run(
        [sys.executable, "-m", module, "--help"], capture_output=True, text=True, timeout=120, check=False
    )
    assert done.returncode == 0, done.stderr
    return done.stdout


def _run(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", *args], capture_output=True, text=True, timeout=120, check=False)


def test_experiments_help_exits_0():
    out = _help("primfit.research.experiments")
    assert "python -m primfit.research.experiments" in out and "table" in out and "evaluate" in out
    table = _run("primfit.research.experiments", "table", "--help")
    assert table.returncode == 0 and "--out" in table.stdout
    evaluate = _run("primfit.research.experiments", "evaluate", "--help")
    assert evaluate.returncode == 0 and "--model" in evaluate.stdout and "--json" in evaluate.stdout


def test_pretrained_help_exits_0():
    require("torch")
    out = _help("primfit.research.pretrained")
    assert "python -m primfit.research.pretrained" in out and "--out" in out


def test_train_help_exits_0():
    require("torch")  # train imports torch at the top
    out = _help("primfit.research.train")
    assert "python -m primfit.research.train" in out and "--arch" in out


def test_warm_start_help_exits_0():
    require("torch")
    out = _help("primfit.research.warm_start")
    assert "python -m primfit.research.warm_start" in out and "--pipe" in out
