#!/usr/bin/env bash
# Runs every test of the project: Rust (all crates, unit + integration + doc tests),
# then the Python package (wheel built by maturin into a virtualenv; mypy stubtest of the
# extension stub, mypy of the package; pytest).
#
#   scripts/test.sh            # what the README and CI run
#
# Environment:
#   PRIMFIT_VENV         virtualenv to use/create (default: ~/.cache/primfit-ci/venv-<hash of
#                        python/requirements-ci.txt>, outside the clone so it is reused)
#   PRIMFIT_REQUIRE_ALL  1 = a skipped test is a failure (CI sets it)
set -euo pipefail
cd "$(dirname "$0")/.."

echo "== cargo test (workspace)"
# Every target but the criterion benches: those are measurements (scripts/bench.sh,
# `cargo bench`), and .ci/run's clippy --all-targets already compiles them.
cargo test --workspace --lib --bins --tests --examples --locked
cargo test --workspace --doc --locked

echo "== python"
req=python/requirements-ci.txt
hash=$(sha256sum "$req" | cut -c1-16)
venv=${PRIMFIT_VENV:-$HOME/.cache/primfit-ci/venv-$hash}
if [ ! -x "$venv/bin/python" ] || [ ! -f "$venv/.complete" ]; then
    echo "creating $venv (first run downloads torch: several GB)"
    rm -rf "$venv"
    python3 -m venv "$venv"
    "$venv/bin/pip" install -q --upgrade pip
    "$venv/bin/pip" install -q -r "$req"
    touch "$venv/.complete"
fi
rm -rf target/wheels
"$venv/bin/maturin" build --release -q -m crates/py/Cargo.toml -i "$venv/bin/python" --out target/wheels
"$venv/bin/pip" install -q --force-reinstall --no-deps target/wheels/primfit-*.whl
# The hand-written stub of the extension module against the compiled module, then the
# package's own annotations (its sources; the stub stands in for the extension).
"$venv/bin/python" -m mypy.stubtest primfit._primfit
"$venv/bin/python" -m mypy --cache-dir target/mypy crates/py/python/primfit
"$venv/bin/python" -m pytest -q crates/py/tests -p no:cacheprovider
