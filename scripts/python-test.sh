#!/usr/bin/env bash
# Tests the Python package: builds it (python/, PyO3 and maturin) into a fresh virtual
# environment, with pytest and the optional packages, and runs python/tests against the `deasim`
# command line of the same tree. The Rust build reuses the repository's target directory unless CARGO_TARGET_DIR is set.
set -euo pipefail
cd "$(dirname "$0")/.."
root="$PWD"
venv="$root/target/python-venv"
rm -rf "$venv"
python3 -m venv "$venv"
# the command line the tests compare with
cargo build --release
export CARGO_TARGET_DIR="${CARGO_TARGET_DIR:-$root/target}"
"$venv/bin/python" -m pip install --quiet --upgrade pip
# with the optional packages the tests use: meshio (VTU round trip), and matplotlib, scipy and
# python-control for the worked example of docs/python.md
"$venv/bin/python" -m pip install --quiet "./python[test]" meshio matplotlib scipy control
# from the root: `python -m pytest` puts the working directory first on the path, and python/
# holds the package's sources without its compiled module
DEASIM_BIN="$root/target/release/deasim" "$venv/bin/python" -m pytest -q -p no:cacheprovider python/tests
