"""Tiled fitting of surveys beyond one machine on a Dask cluster (issue 18).

:func:`fit_tiled` cuts the survey's xy box into square tiles, fits each tile with a halo
of its neighbours' points on a Dask worker (the Rust fit, GIL released), and merges the
tiles on the coordinator: a primitive is owned by the tile holding its centre, coplanar
planes and collinear cylinders crossing a seam are joined, and duplicates are dropped by
an existence re-check on the seam points. The result is in the input's frame.

A file source (LAS/LAZ) is never held whole and is read once: the workers first split
it, each over its own range of the file's points, into per-tile spill files (24 bytes a
point, in a temporary folder beside the survey or in ``spill_dir``: it must be on a
filesystem every worker sees, as the survey itself is), then each worker fits a tile
from its spill files. A worker's memory is bounded by its tile, and the coordinator
holds only primitives and seam points. Other formats are read whole by each worker
(convert a survey to LAZ to tile it).

Needs the optional ``dask`` extra: ``pip install primfit[dask]``. Also a command line,
``python -m primfit.dask SURVEY.laz --scheduler ADDRESS``, which ``primfit fit --tiles
--scheduler`` runs.
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import sys
import tempfile
import time
from collections.abc import Sequence
from typing import Any

import numpy as np
import numpy.typing as npt

from . import FitResult, _fit_options, _primfit, write_mesh
from ._convert import _points

__all__ = ["fit_tiled", "main"]

#: Points a splitter reads at least: a survey smaller than two of these is split by one.
SPLIT_MIN_POINTS = 2_000_000


def _distributed() -> Any:
    """The ``distributed`` package, or an ImportError naming the extra."""
    try:
        import distributed
    except ImportError as e:
        raise ImportError(
            "primfit.dask needs dask and distributed: pip install primfit[dask]"
        ) from e
    return distributed


def _match_worker_threads() -> None:
    """In a worker process of its own: the Rust thread pool gets the worker's threads
    (``nthreads``), not one per core, so that ``n`` workers of one thread on ``n`` cores
    do not run ``n²`` threads. Left alone when ``RAYON_NUM_THREADS`` is set, outside a
    worker, and in a worker that shares the caller's process."""
    import multiprocessing

    if "RAYON_NUM_THREADS" in os.environ or multiprocessing.parent_process() is None:
        return
    try:
        nthreads = _distributed().get_worker().state.nthreads
    except ValueError:
        return
    os.environ["RAYON_NUM_THREADS"] = str(max(1, int(nthreads)))


def _fit_file_tile(path: str, grid: str, tile: int, options: dict[str, Any]) -> str:
    """On a worker: tile ``tile``'s points read from ``path``, fitted; the tile's JSON."""
    _match_worker_threads()
    points = _primfit.tile_points(path, grid, tile)
    return _primfit.fit_tile(points, grid, tile, _fit_options(options))


def _split_part(path: str, grid: str, first: int, count: int, spill: str, part: int) -> list[int]:
    """On a worker: points ``first .. first + count`` of ``path`` into spill files."""
    _match_worker_threads()
    return _primfit.split_survey(path, grid, first, count, spill, part)


def _fit_spilled_tile(
    spill: str, parts: int, expected: int, grid: str, tile: int, options: dict[str, Any]
) -> str:
    """On a worker: tile ``tile`` read from its spill files, fitted; the tile's JSON."""
    _match_worker_threads()
    points = _primfit.spilled_tile_points(spill, tile, parts)
    if len(points) != expected:
        raise OSError(
            f"tile {tile}: {len(points)} of its {expected} points are in the spill folder "
            f"{spill}: the workers do not share it (pass spill_dir= on a shared filesystem)"
        )
    return _primfit.fit_tile(points, grid, tile, _fit_options(options))


def _is_las(path: str) -> bool:
    """Whether ``path`` starts as a LAS/LAZ file does (``LASF``)."""
    with open(path, "rb") as f:
        return f.read(4) == b"LASF"


def _spill_folder(path: str, spill_dir: str | os.PathLike[str] | None) -> str:
    """A new folder for the spill files: in ``spill_dir``, else beside the survey (where
    the workers that read the survey can reach it), else in the system's temp folder."""
    if spill_dir is not None:
        return tempfile.mkdtemp(prefix="primfit-tiles-", dir=os.fspath(spill_dir))
    try:
        return tempfile.mkdtemp(prefix=".primfit-tiles-", dir=os.path.dirname(os.path.abspath(path)))
    except OSError:
        return tempfile.mkdtemp(prefix="primfit-tiles-")


def _fit_split_file(
    client: Any, distributed: Any, path: str, grid: str, points: int, spill: str,
    fit_options: dict[str, Any], progress: bool,
) -> FitResult:
    """The survey ``path`` split once by the workers, then fitted tile by tile."""
    workers = max(1, len(client.scheduler_info().get("workers", {})))
    parts = max(1, min(workers, points // SPLIT_MIN_POINTS))
    step = -(-points // parts)
    splits = [
        client.submit(_split_part, path, grid, k * step, step, spill, k, pure=False)
        for k in range(parts)
    ]
    t0 = time.monotonic()
    received = [0] * (json.loads(grid)["nx"] * json.loads(grid)["ny"])
    for done, future in enumerate(distributed.as_completed(splits), start=1):
        for t, c in enumerate(future.result()):
            received[t] += c
        if progress:
            print(f"split {done}/{parts} ({time.monotonic() - t0:.1f} s)", file=sys.stderr)
    futures = [
        client.submit(_fit_spilled_tile, spill, parts, n, grid, t, fit_options, pure=False)
        for t, n in enumerate(received)
        if n > 0
    ]
    return _gather(distributed, futures, progress)


def _fit_array_tile(points: np.ndarray, grid: str, tile: int, options: dict[str, Any]) -> str:
    """On a worker: tile ``tile`` fitted from ``points`` (its haloed box); the tile's JSON.
    An array that arrived by pickle protocol 5 may lie unaligned in its buffer: copied
    to an aligned one first (the extension reads aligned float64 only)."""
    _match_worker_threads()
    aligned = np.require(points, dtype=np.float64, requirements=["C", "A"])
    return _primfit.fit_tile(aligned, grid, tile, _fit_options(options))


def _haloed(points: np.ndarray, grid: dict[str, Any], tile: int) -> np.ndarray:
    """The points of ``tile``'s haloed box (as the Rust ``TileGrid::in_haloed``: border
    tiles reach to infinity outwards)."""
    nx, ny, size, halo = grid["nx"], grid["ny"], grid["tile_size"], grid["halo"]
    i, j = tile % nx, tile // nx
    x0 = grid["origin"][0] + i * size
    y0 = grid["origin"][1] + j * size
    x, y = points[:, 0], points[:, 1]
    keep = np.ones(len(points), dtype=bool)
    if i > 0:
        keep &= x >= x0 - halo
    if i + 1 < nx:
        keep &= x <= x0 + size + halo
    if j > 0:
        keep &= y >= y0 - halo
    if j + 1 < ny:
        keep &= y <= y0 + size + halo
    return np.ascontiguousarray(points[keep])


def fit_tiled(
    source: str | os.PathLike[str] | npt.ArrayLike,
    *,
    tile_size: float | None = None,
    halo: float | None = None,
    client: Any = None,
    progress: bool = False,
    spill_dir: str | os.PathLike[str] | None = None,
    **fit_options: Any,
) -> FitResult:
    """Fits ``source`` tile by tile on a Dask cluster and merges the tiles.

    Parameters
    ----------
    source : path or (J, 3) array-like
        A survey file (LAS/LAZ read in batches on the workers; PLY and the other
        formats of :func:`primfit.read_ply`'s reader read whole) or the points.
    tile_size : float
        Side of a tile in scene units (default: about 500 000 points per tile).
    halo : float
        Neighbouring points each tile is fitted with, scene units (default tile_size / 10).
    client : distributed.Client
        The cluster to use; ``None`` starts a ``LocalCluster`` with one worker per core
        (and closes it afterwards).
    progress : bool
        Print one line per finished tile on stderr.
    spill_dir : path
        LAS/LAZ sources: where the per-tile spill files go (a temporary folder in it,
        removed afterwards; about 24 bytes × points × 1.2 of disk). It must be on a
        filesystem every worker sees. Default: beside the survey.
    **fit_options
        Options of :func:`primfit.fit`, applied to every tile.

    Returns
    -------
    FitResult
        The merged primitives; its ``metrics`` are the tiles' measures joined (means
        weighted by points, p95 and max the largest tile's), each tile measured against
        its own model.
    """
    distributed = _distributed()
    _fit_options(fit_options)  # bad options fail here, once, before any tile starts
    own = client is None
    if own:
        cluster = distributed.LocalCluster(
            n_workers=os.cpu_count() or 1, threads_per_worker=1, dashboard_address=":0"
        )
        client = distributed.Client(cluster)
    try:
        if isinstance(source, (str, os.PathLike)):
            path = os.fspath(source)
            grid, count = _primfit.tile_grid_file(path, tile_size, halo)
            if _is_las(path):
                spill = _spill_folder(path, spill_dir)
                try:
                    return _fit_split_file(
                        client, distributed, path, grid, count, spill, fit_options, progress
                    )
                finally:
                    shutil.rmtree(spill, ignore_errors=True)
            tiles = range(json.loads(grid)["nx"] * json.loads(grid)["ny"])
            futures = [
                client.submit(_fit_file_tile, path, grid, t, fit_options, pure=False)
                for t in tiles
            ]
        else:
            points = _points("cloud", source)
            grid = _primfit.tile_grid_array(points, tile_size, halo)
            g = json.loads(grid)
            futures = []
            for t in range(g["nx"] * g["ny"]):
                part = client.scatter(_haloed(points, g, t))
                futures.append(client.submit(_fit_array_tile, part, grid, t, fit_options, pure=False))
        return _gather(distributed, futures, progress)
    finally:
        if own:
            client.close()
            cluster.close()


def _gather(distributed: Any, futures: Sequence[Any], progress: bool) -> FitResult:
    """The tiles' documents as they finish (one progress line each), merged."""
    docs: list[str] = []
    t0 = time.monotonic()
    for done, future in enumerate(distributed.as_completed(futures), start=1):
        docs.append(future.result())
        if progress:
            rate = done / max(time.monotonic() - t0, 1e-9)
            print(f"tile {done}/{len(futures)} ({rate:.2f} tiles/s)", file=sys.stderr)
    t1 = time.monotonic()
    result = FitResult(*_primfit.merge_tiles(docs))
    if progress:
        print(f"merged {len(docs)} tiles in {time.monotonic() - t1:.1f} s", file=sys.stderr)
    return result


def main(argv: Sequence[str] | None = None) -> int:
    """``python -m primfit.dask SURVEY --scheduler ADDRESS [-o result.json] [--mesh M]``."""
    parser = argparse.ArgumentParser(prog="python -m primfit.dask", description=__doc__.splitlines()[0])
    parser.add_argument("scene")
    parser.add_argument("--scheduler", default="local", help="scheduler address, or 'local'")
    parser.add_argument("--tile-size", type=float)
    parser.add_argument("--halo", type=float)
    parser.add_argument("--workers", type=int, help="'local' only: workers (default one per core)")
    parser.add_argument("--memory-limit", help="'local' only: per worker, e.g. 4GiB")
    parser.add_argument("--spill-dir", help="LAS/LAZ: where the per-tile spill files go")
    parser.add_argument("-o", "--output")
    parser.add_argument("--mesh")
    parser.add_argument("--quiet", action="store_true")
    a = parser.parse_args(argv)
    distributed = _distributed()
    t0 = time.monotonic()
    if a.scheduler == "local":
        cluster = distributed.LocalCluster(
            n_workers=a.workers or os.cpu_count() or 1,
            threads_per_worker=1,
            memory_limit=a.memory_limit or "auto",
            dashboard_address=":0",
        )
        client = distributed.Client(cluster)
    else:
        cluster, client = None, distributed.Client(a.scheduler)
    try:
        result = fit_tiled(
            a.scene,
            tile_size=a.tile_size,
            halo=a.halo,
            client=client,
            progress=not a.quiet,
            spill_dir=a.spill_dir,
        )
    except (ValueError, OSError) as e:
        print(f"error: {e}", file=sys.stderr)
        return 1
    finally:
        client.close()
        if cluster is not None:
            cluster.close()
    if a.output:
        doc = json.loads(result.to_json())
        doc["settings"]["scene"] = a.scene
        with open(a.output, "w", encoding="utf-8") as f:
            json.dump(doc, f, indent=2)
    if a.mesh:
        write_mesh(a.mesh, result)
    if not a.quiet:
        m = result.metrics
        print(
            f"{a.scene}: {m['points']} points → {len(result)} primitives in "
            f"{time.monotonic() - t0:.1f} s; point→model mean {m['point_to_model_mean']:.4f}"
        )
    return 0


if __name__ == "__main__":
    # Through the importable module, so that the tasks pickle as primfit.dask functions
    # (not __main__ ones, which the workers cannot import).
    from primfit.dask import main as _main

    sys.exit(_main())
