"""Shared fixtures: the real data set lives beside the repository, never inside it."""

from __future__ import annotations

from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
DATA = REPO.parent / "shared" / "data"


@pytest.fixture(scope="session")
def shared_data() -> Path:
    """../shared/data: every developer machine and CI have it; a missing copy is an error."""
    assert DATA.is_dir(), f"real data not found at {DATA} (see README.md)"
    return DATA
