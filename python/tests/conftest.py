"""Shared fixtures: the shared real data (../shared/data beside the repository) and the CLI
binary built by `cargo build --release` (or `cargo test --release`), whose outputs the package's
results are compared with."""

import os
import subprocess
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
DATA = Path(os.environ.get("MESHMATCH_DATA", ROOT.parent / "shared" / "data"))


@pytest.fixture(scope="session")
def data():
    if not DATA.is_dir():
        pytest.fail(f"{DATA}: the shared data must lie beside the repository")
    return DATA


@pytest.fixture(scope="session")
def cli():
    """Run the meshmatch CLI; returns its stderr."""
    exe = Path(os.environ.get("MESHMATCH_CLI", ROOT / "target" / "release" / "meshmatch"))
    if not exe.is_file():
        pytest.fail(f"{exe}: build the CLI first (cargo build --release) or set MESHMATCH_CLI")

    def run(*args):
        r = subprocess.run([str(exe), *map(str, args)], capture_output=True, text=True)
        assert r.returncode == 0, f"meshmatch {' '.join(map(str, args))}: {r.stderr}"
        return r.stderr

    return run
