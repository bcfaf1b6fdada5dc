#!/usr/bin/env bash
# The reader mutation suite (crates/core/tests/formats/mutations.rs) with more cases than
# CI runs: every format's seed files damaged CASES times each (default 5000; CI: 300), the
# outcome table printed as the README's "Reliability" section quotes it.
#
#   scripts/fuzz_readers.sh [CASES]
set -euo pipefail
cd "$(dirname "$0")/.."
PRIMFIT_MUTATION_CASES=${1:-5000} cargo test --release --locked -p primfit-core --test formats \
    mutations::every_reader_survives -- --nocapture
