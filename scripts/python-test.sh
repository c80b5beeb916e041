#!/usr/bin/env bash
# The Python package (python/): build and install it into a virtualenv in target/pyvenv the
# way a user does (`pip install ./python`), then run its tests and examples with pytest.
# Needs python3 with venv and pip; everything else comes from PyPI and crates.io.
set -euo pipefail
cd "$(dirname "$0")/.."

venv=target/pyvenv
if [ ! -x "$venv/bin/python" ]; then
    python3 -m venv "$venv"
fi
# shellcheck disable=SC1091
. "$venv/bin/activate"
pip install --quiet --disable-pip-version-check -r python/requirements-test.txt
pip install --quiet --disable-pip-version-check ./python

# The CLI the tests compare with (cargo test builds it; build it here when run alone).
export TISSUE_BIN="${TISSUE_BIN:-$PWD/target/release/tissue}"
if [ ! -x "$TISSUE_BIN" ]; then
    cargo build --release --locked -p tissue-cli
fi
# From the root, so that `import tissue` is the installed package, not python/tissue/.
pytest -q python/tests
