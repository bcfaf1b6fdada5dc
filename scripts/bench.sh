#!/usr/bin/env bash
# The benchmark of the README's Performance section (issue 15), in one run:
#
#   1. what users run: `primfit fit SCAN` with its defaults on every scene (bundled
#      examples, synthetic hallways of 20k to 10M points), stage by stage, on all cores
#      and on one, next to the lattice fit, with peak RSS; the lattice fit against its
#      candidate count; the scaling plot (benches/pipeline_bench.py);
#   2. the peers a user would pick instead, on the same scans in the same run: CGAL
#      Efficient RANSAC (with Open3D normals) and Open3D's plane loop, all measured by
#      one independent measure (benches/real_scan_compare.py);
#   3. like for like: the lattice fit against the NumPy/SciPy reference of the thesis's
#      approach on the same candidates (crates/core/examples/bench_table.rs with
#      benches/numpy_reference.py).
#
#   scripts/bench.sh                     # everything (~25 minutes on 2 cores)
#   PRIMFIT_BENCH_PARTS=1 scripts/bench.sh                 # any of 1,2,3
#   PRIMFIT_BENCH_SCENES=hallway-20k,table_mug scripts/bench.sh
#
# Environment:
#   PRIMFIT_BENCH_PYTHON  Python with numpy, scipy, matplotlib, plyfile, open3d and cgal.
#                         Default: a virtualenv created once in
#                         ~/.cache/primfit-bench-venv (Open3D needs Debian's libusb-1.0-0).
#   PRIMFIT_BENCH_OUT     Where results, meshes and the plot go [default: /tmp/primfit_bench].
#
# Timings are only meaningful on an otherwise idle machine: each part prints the CPU,
# core count, memory and the load average at its start.
set -euo pipefail
cd "$(dirname "$0")/.."

parts=${PRIMFIT_BENCH_PARTS:-1,2,3}
out=${PRIMFIT_BENCH_OUT:-/tmp/primfit_bench}
mkdir -p "$out"

cargo build --release --locked -p primfit-cli
cargo build --release --locked -p primfit-core --example bench_table
target=${CARGO_TARGET_DIR:-target}
primfit=$target/release/primfit

py=${PRIMFIT_BENCH_PYTHON:-}
if [ -z "$py" ]; then
    venv=$HOME/.cache/primfit-bench-venv
    if [ ! -f "$venv/.complete" ]; then
        echo "creating $venv (numpy, scipy, matplotlib, plyfile, open3d, cgal)" >&2
        rm -rf "$venv"
        python3 -m venv "$venv"
        "$venv/bin/pip" install -q numpy scipy matplotlib plyfile open3d cgal
        touch "$venv/.complete"
    fi
    py=$venv/bin/python
fi

if [[ $parts == *1* ]]; then
    echo "## 1. The default pipeline, stage by stage"
    echo
    "$py" benches/pipeline_bench.py --primfit "$primfit" --out "$out/pipeline" \
        ${PRIMFIT_BENCH_SCENES:+--scenes "$PRIMFIT_BENCH_SCENES"} --plot docs/bench/scaling.png
    echo
fi
if [[ $parts == *2* ]]; then
    echo "## 2. Against CGAL Efficient RANSAC and Open3D"
    echo
    "$py" benches/real_scan_compare.py --primfit "$primfit" --out "$out/peers" \
        --scans examples/hallway.ply examples/plane_scan.ply examples/table_mug.ply --synth pipe
    echo
fi
if [[ $parts == *3* ]]; then
    echo "## 3. Like for like: the lattice fit against the NumPy/SciPy reference"
    echo
    # The existence model (the default) with and without the discrete polish (the
    # reference runs none), the independent model (the issue's own measurement), 1M.
    like=pipe-20k,pipe-20k-nopolish,hallway-20k,hallway-20k-nopolish
    like=$like,pipe-20k-indep,hallway-20k-indep,hallway-1m
    "$target/release/examples/bench_table" --numpy "$py" --scenes "$like" --numpy-scenes "$like"
fi
