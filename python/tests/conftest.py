"""Shared fixtures: the `deasim` command line the package is compared with."""

import os
import shutil
import subprocess
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="session")
def cli():
    """Runs the `deasim` binary ($DEASIM_BIN, else the repository's target/release/deasim, else
    the one on PATH) with the given arguments in a directory; returns the completed process."""
    candidates = [os.environ.get("DEASIM_BIN"), str(REPO / "target" / "release" / "deasim")]
    binary = next((c for c in candidates if c and Path(c).is_file()), None) or shutil.which(
        "deasim"
    )
    if binary is None:
        pytest.fail("no deasim binary: build it (cargo build --release) or set DEASIM_BIN")

    def run(args, cwd):
        p = subprocess.run(
            [binary, *args], cwd=cwd, capture_output=True, text=True, check=False
        )
        assert p.returncode == 0, p.stderr
        return p

    return run
