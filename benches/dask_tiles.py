"""Tiled fitting on a LocalCluster: wall time, tiles per second and peak worker memory.

    python benches/dask_tiles.py SURVEY.laz --workers 2 --memory-limit 4GiB [--tile-size S]

Peak worker memory is each worker process's peak resident set (``ru_maxrss``), read on
the workers after the fit.
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import time

import distributed

import primfit.dask


def _peak_rss_bytes() -> int:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024


def main() -> None:
    p = argparse.ArgumentParser()
    p.add_argument("survey")
    p.add_argument("--workers", type=int, default=2)
    p.add_argument("--memory-limit", default="4GiB")
    p.add_argument("--tile-size", type=float)
    a = p.parse_args()
    with distributed.LocalCluster(
        n_workers=a.workers, threads_per_worker=1, memory_limit=a.memory_limit, dashboard_address=":0"
    ) as cluster, distributed.Client(cluster) as client:
        grid, points = primfit._primfit.tile_grid_file(a.survey, a.tile_size, None)
        g = json.loads(grid)
        load_start = os.getloadavg()[0]
        t0 = time.monotonic()
        result = primfit.dask.fit_tiled(
            a.survey, tile_size=g["tile_size"], client=client, progress=True
        )
        wall = time.monotonic() - t0
        peaks = client.run(_peak_rss_bytes)
    tiles = g["nx"] * g["ny"]
    print(json.dumps({
        "survey": a.survey, "points": points, "workers": a.workers, "memory_limit": a.memory_limit,
        "tiles": tiles, "tile_size": g["tile_size"], "halo": g["halo"], "wall_s": round(wall, 1),
        "tiles_per_s": round(tiles / wall, 4), "peak_worker_rss_mib": max(peaks.values()) // 2**20,
        "primitives": len(result),
        "types": {t: sum(p["type"] == t for p in result.primitives) for t in {p["type"] for p in result.primitives}},
        "point_to_model_mean": result.metrics["point_to_model_mean"],
        "coordinator_peak_rss_mib": _peak_rss_bytes() // 2**20,
        "load_1min_start": load_start, "load_1min_end": os.getloadavg()[0],
    }))


if __name__ == "__main__":
    main()
