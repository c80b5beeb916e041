#!/usr/bin/env bash
# Every check CI runs, in the order CI runs them. Run it before pushing.
set -euo pipefail
cd "$(dirname "$0")/.."

echo "== format"
cargo fmt --all -- --check

echo "== lint (all targets: the benchmarks are type-checked here, not built)"
cargo clippy --workspace --all-targets --locked -- -D warnings

echo "== tests (release: faer's generic code is very slow unoptimised)"
cargo test --release --workspace --locked

echo "== python (pip install ./python, pytest)"
bash scripts/python-test.sh

echo "== browser (the viewer in headless Chromium)"
bash scripts/browser-test.sh
