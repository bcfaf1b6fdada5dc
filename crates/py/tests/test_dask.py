"""primfit.dask: tiled fitting on a small LocalCluster against one fit of the same floor."""

from __future__ import annotations

import os
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import struct

import numpy as np
import pytest

import primfit
import primfit.dask

from conftest import require

TILE = 6.0  # metres: the 16 × 8 m floor below is 3 × 2 tiles


def _floor(n: int = 24_000, seed: int = 3) -> np.ndarray:
    """A 16 × 8 m floor, walls every 4 m (3 m high) and a pipe along x: every wall along x,
    the floor and the pipe cross tile seams."""
    rng = np.random.default_rng(seed)
    parts: list[np.ndarray] = []

    def rect(origin: np.ndarray, u: np.ndarray, v: np.ndarray, k: int) -> None:
        a, b = rng.random((k, 1)), rng.random((k, 1))
        parts.append(origin + a * u + b * v)

    x, y, h = np.array([16.0, 0, 0]), np.array([0, 8.0, 0]), np.array([0, 0, 3.0])
    rect(np.zeros(3), x, y, n // 3)
    for wx in (0.0, 4.0, 8.0, 12.0, 16.0):
        rect(np.array([wx, 0, 0]), y, h, n // 30)
    for wy in (0.0, 4.0, 8.0):
        rect(np.array([0, wy, 0]), x, h, n // 15)
    t, s = rng.random(n // 20) * 2 * np.pi, rng.random(n // 20) * 16.0
    parts.append(np.stack([s, 2.0 + 0.08 * np.cos(t), 2.6 + 0.08 * np.sin(t)], axis=1))
    cloud = np.concatenate(parts)
    return cloud + rng.normal(scale=0.002, size=cloud.shape)


@pytest.fixture(scope="module")
def client() -> Iterator[Any]:
    distributed = require("distributed")
    with distributed.LocalCluster(
        n_workers=2, threads_per_worker=1, processes=False, dashboard_address=":0"
    ) as cluster, distributed.Client(cluster) as c:
        yield c


def test_tiled_fit_matches_one_fit(client: Any) -> None:
    cloud = _floor()
    single = primfit.fit(cloud)
    tiled = primfit.dask.fit_tiled(cloud, tile_size=TILE, client=client)
    assert abs(len(tiled) - len(single)) <= max(1, round(0.02 * len(single))), (tiled, single)
    assert tiled.metrics["points"] == len(cloud)
    assert tiled.metrics["point_to_model_mean"] <= 1.05 * single.metrics["point_to_model_mean"] + 1e-3
    assert sum(p["type"] == "cylinder" for p in tiled.primitives) == 1


def _write_las(path: Path, cloud: np.ndarray, scale: float = 0.001) -> None:
    """``cloud`` as a LAS 1.2 file, point format 0 (a 227-byte header, 20 bytes a point)."""
    offset = np.floor(cloud.min(axis=0))
    lo, hi = cloud.min(axis=0), cloud.max(axis=0)
    header = struct.pack(
        "<4sHH16sBB32s32sHHHIIBHI5I3d3d6d",
        b"LASF", 0, 0, bytes(16), 1, 2, b"primfit test".ljust(32, b"\0"),
        b"primfit".ljust(32, b"\0"), 1, 2026, 227, 227, 0, 0, 20, len(cloud),
        len(cloud), 0, 0, 0, 0, scale, scale, scale, *offset,
        hi[0], lo[0], hi[1], lo[1], hi[2], lo[2],
    )
    assert len(header) == 227
    records = np.zeros(len(cloud), dtype=[("xyz", "<i4", 3), ("rest", "V8")])
    records["xyz"] = np.round((cloud - offset) / scale).astype("<i4")
    path.write_bytes(header + records.tobytes())


def test_a_las_file_is_split_once_and_fitted_tile_by_tile(
    client: Any, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    cloud = _floor(12_000)
    path = tmp_path / "floor.las"
    _write_las(path, cloud)
    assert primfit.read_ply(path)["points"].shape == cloud.shape
    # Two splitters (one per worker), each over half of the file's points.
    monkeypatch.setattr(primfit.dask, "SPLIT_MIN_POINTS", 5_000)
    from_file = primfit.dask.fit_tiled(path, tile_size=TILE, client=client)
    from_array = primfit.dask.fit_tiled(cloud, tile_size=TILE, client=client)
    assert abs(len(from_file) - len(from_array)) <= 1
    assert from_file.metrics["points"] == len(cloud)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["floor.las"]  # spill removed
    spill = tmp_path / "spill"
    spill.mkdir()
    primfit.dask.fit_tiled(path, tile_size=TILE, client=client, spill_dir=spill)
    assert list(spill.iterdir()) == []


def test_a_spill_folder_the_worker_cannot_see_is_one_clear_error(tmp_path: Path) -> None:
    grid = primfit._primfit.tile_grid_array(_floor(2_000), TILE, None)
    with pytest.raises(OSError, match="spill_dir"):
        primfit.dask._fit_spilled_tile(str(tmp_path), 2, 500, grid, 0, {})


def test_bad_input_is_one_clear_error(client: Any, tmp_path: Path) -> None:
    cloud = _floor(2_000)
    with pytest.raises(ValueError, match="tile_size"):
        primfit.dask.fit_tiled(cloud, tile_size=-1.0, client=client)
    with pytest.raises(ValueError, match="halo"):
        primfit.dask.fit_tiled(cloud, tile_size=4.0, halo=5.0, client=client)
    with pytest.raises(ValueError):
        primfit.dask.fit_tiled(cloud, tile_size=4.0, client=client, beta="no")
    with pytest.raises(OSError):
        primfit.dask.fit_tiled(tmp_path / "missing.laz", tile_size=4.0, client=client)


def _rayon_threads_on_worker() -> str | None:
    primfit.dask._match_worker_threads()
    return os.environ.get("RAYON_NUM_THREADS")


def test_a_worker_process_fits_with_its_own_threads_only() -> None:
    distributed = require("distributed")
    with distributed.LocalCluster(
        n_workers=1, threads_per_worker=1, dashboard_address=":0"
    ) as cluster, distributed.Client(cluster) as c:
        want = os.environ.get("RAYON_NUM_THREADS", "1")  # one set by the caller is kept
        assert c.submit(_rayon_threads_on_worker, pure=False).result() == want
