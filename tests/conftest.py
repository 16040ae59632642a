"""Shared fixtures: the real data set lives beside the repository, never inside it."""

from __future__ import annotations

import os
from pathlib import Path

from mocapzip.defaults import BLAS_THREAD_VARIABLES

# One BLAS thread per process, set before numpy loads: the codec runs worker processes, and
# on a 2-core machine threaded BLAS inside each made eigendecompositions about 8x slower.
for _var in BLAS_THREAD_VARIABLES:
    os.environ.setdefault(_var, "1")

import pytest

REPO = Path(__file__).resolve().parents[1]
DATA = REPO.parent / "shared" / "data"


def pytest_report_header(config) -> str:
    """Say which copy of mocapzip is under test (`pytest -q` hides it; see it with `pytest`).

    Editable install, or run from the repository root: the tree (mocapzip/__init__.py finds
    formats/ and cli/ beside it). A wheel, run from outside the repository: the installed copy.
    """
    import mocapzip.formats  # binds mocapzip too

    return f"mocapzip under test: {Path(mocapzip.__file__).parent} (formats: {Path(mocapzip.formats.__file__).parent})"


@pytest.fixture(scope="session")
def shared_data() -> Path:
    """../shared/data: every developer machine and CI have it; a missing copy is an error."""
    assert DATA.is_dir(), f"real data not found at {DATA} (see README.md)"
    return DATA
