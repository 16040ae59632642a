"""Shared fixtures: the real data set lives beside the repository, never inside it."""

from __future__ import annotations

import os
from pathlib import Path

# One BLAS thread per process, set before numpy loads: the codec runs worker processes, and
# on a 2-core machine threaded BLAS inside each made eigendecompositions about 8x slower.
for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import pytest

REPO = Path(__file__).resolve().parents[1]
DATA = REPO.parent / "shared" / "data"


@pytest.fixture(scope="session")
def shared_data() -> Path:
    """../shared/data: every developer machine and CI have it; a missing copy is an error."""
    assert DATA.is_dir(), f"real data not found at {DATA} (see README.md)"
    return DATA
