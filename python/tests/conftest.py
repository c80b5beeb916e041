"""Shared fixtures: the repository's files and the `tissue` binary the CLI tests compare with."""

import os
import shutil
from pathlib import Path

import pytest

import tissue

REPO = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="session")
def repo() -> Path:
    return REPO


@pytest.fixture(scope="session")
def liver() -> "tissue.Mesh":
    """The shipped liver in metres (about 1,500 tetrahedra)."""
    return tissue.Mesh.read(REPO / "assets" / "meshes" / "liver.msh").scaled(0.01)


@pytest.fixture(scope="session")
def tissue_bin() -> str:
    """The `tissue` command: TISSUE_BIN, the workspace's release build, or PATH."""
    for candidate in (
        os.environ.get("TISSUE_BIN"),
        str(REPO / "target" / "release" / "tissue"),
        shutil.which("tissue"),
    ):
        if candidate and Path(candidate).is_file():
            return candidate
    pytest.fail("no `tissue` binary: build it (cargo build --release -p tissue-cli) or set TISSUE_BIN")
