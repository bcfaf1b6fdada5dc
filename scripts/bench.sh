#!/usr/bin/env bash
# The reproducible benchmark table (DESIGN §5, issue 4): builds the release fitter, makes
# sure a Python with NumPy + SciPy is at hand, then runs crates/core/examples/bench_table.rs, which
# fits every scene in its own child process (1 thread and all cores) and runs the
# NumPy/SciPy reference (benches/numpy_reference.py) on the same scenes, and prints one
# markdown table plus per-stage timings.
#
#   scripts/bench.sh                         # the default table (~10 minutes on 2 cores)
#   scripts/bench.sh --scenes pipe-20k       # any bench_table option passes through
#   PRIMFIT_BENCH_NUMPY=0 scripts/bench.sh   # Rust only
#
# Environment:
#   PRIMFIT_BENCH_PYTHON  Python to use for the reference (must import numpy and scipy).
#                         Default: the CI venv (~/.cache/primfit-ci/venv-<hash>) when it is
#                         complete, else a small venv with numpy + scipy created once in
#                         ${TMPDIR:-/tmp}/primfit-bench-venv.
#   PRIMFIT_BENCH_NUMPY   0 = skip the NumPy reference.
#   PRIMFIT_BENCH_JSON    also write the raw measurements to this file.
#
# Timings are only meaningful on an otherwise idle machine: the table's first line
# records the CPU, core count, memory and the load average at the start.
set -euo pipefail
cd "$(dirname "$0")/.."

cargo build --release --locked --example bench_table

args=("$@")
if [ "${PRIMFIT_BENCH_NUMPY:-1}" != 0 ]; then
    py=${PRIMFIT_BENCH_PYTHON:-}
    if [ -z "$py" ]; then
        hash=$(sha256sum python/requirements-ci.txt | cut -c1-16)
        ci=$HOME/.cache/primfit-ci/venv-$hash
        if [ -f "$ci/.complete" ] && "$ci/bin/python" -c 'import numpy, scipy' 2>/dev/null; then
            py=$ci/bin/python
        else
            venv=${TMPDIR:-/tmp}/primfit-bench-venv
            if [ ! -f "$venv/.complete" ]; then
                echo "creating $venv (numpy, scipy)" >&2
                rm -rf "$venv"
                python3 -m venv "$venv"
                "$venv/bin/pip" install -q numpy scipy
                touch "$venv/.complete"
            fi
            py=$venv/bin/python
        fi
    fi
    "$py" -c 'import numpy, scipy; print("NumPy", numpy.__version__, "SciPy", scipy.__version__)' >&2
    args+=(--numpy "$py")
fi
if [ -n "${PRIMFIT_BENCH_JSON:-}" ]; then
    args+=(--json "$PRIMFIT_BENCH_JSON")
fi

# Progress goes to stderr; the table is the only thing on stdout.
target=${CARGO_TARGET_DIR:-target}
"$target/release/examples/bench_table" "${args[@]}"
