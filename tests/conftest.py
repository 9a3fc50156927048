"""Shared fixtures. Markers (slow, getdp, mpi, docs) are defined once, in pyproject.toml."""

from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="session")
def repo() -> Path:
    """The repository root."""
    return REPO
