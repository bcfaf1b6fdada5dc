"""Conversion of array-like inputs to the arrays the extension module takes.

Anything numpy can read (lists, float32, Fortran order, CPU tensors, views of a byte
buffer at an odd offset) becomes a C-ordered, aligned float64 (coordinates,
probabilities) or int64 (indices) array: the extension reads memory in place, and a
misaligned array cannot be read that way. Non-numeric dtypes
(object, str, bool) raise ``TypeError``; a wrong number of dimensions raises
``ValueError``. Shapes, emptiness and finiteness are checked in Rust.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike


def _numeric(name: str, x: ArrayLike, kinds: str) -> np.ndarray:
    """``x`` as an array, whose dtype kind must be one of ``kinds`` (numpy's letters)."""
    a = np.asarray(x)
    if a.dtype.kind not in kinds:
        raise TypeError(f"{name} must be a numeric array, got dtype {a.dtype}")
    return a


def _floats(name: str, x: ArrayLike, ndim: int) -> np.ndarray:
    """``x`` as a C-ordered, aligned float64 array with ``ndim`` dimensions."""
    a = _numeric(name, x, "fiu")
    if a.ndim != ndim:
        raise ValueError(f"{name} must have {ndim} dimension(s), got shape {a.shape}")
    return np.require(a, dtype=np.float64, requirements=["C", "A"])


def _points(name: str, x: ArrayLike) -> np.ndarray:
    """An ``(M, 3)`` float64 array (shape, emptiness and finiteness are checked in Rust)."""
    return _floats(name, x, 2)


def _ints(name: str, x: ArrayLike, ndim: int = 1) -> np.ndarray:
    """``x`` as a C-ordered, aligned int64 array (integer dtypes only: floats are not truncated)."""
    a = _numeric(name, x, "iu")
    if a.ndim != ndim:
        raise ValueError(f"{name} must have {ndim} dimension(s), got shape {a.shape}")
    if a.dtype.kind == "u" and a.size and a.max() > np.iinfo(np.int64).max:
        raise ValueError(f"{name} has an index larger than 2**63 - 1")
    return np.require(a, dtype=np.int64, requirements=["C", "A"])
