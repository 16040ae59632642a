"""Work on the cores `-j` gives (issue 15, deliverable 3): the first pass, the priors, decompress
and `mcz test` in worker processes give what one process gives (the same archive, files,
errors and warnings), hold only a few results at once, and stop cleanly on an error.

Behaviour only: nothing here depends on how fast anything runs.
"""

from __future__ import annotations

import multiprocessing
import os
import warnings
from pathlib import Path

import pytest

from mocapzip.formats.errors import MocapFormatError
from mocapzip.parallel import imap, parallel_map


# --------------------------------------------------------------------------- the pool helper


def _square_with_a_warning(i: int) -> int:
    warnings.warn(f"item {i}")
    return i * i


def _fails_at_three(i: int) -> int:
    if i == 3:
        raise MocapFormatError(f"item {i} is bad", "some/file.amc", 7)
    return i


def _note_start(item: tuple[str, int]) -> int:
    folder, i = item
    Path(folder, str(i)).touch()
    return i


@pytest.mark.parametrize("jobs", [1, 2])
def test_results_and_warnings_come_in_item_order(jobs):
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        results = list(imap(_square_with_a_warning, range(12), jobs, window=3))
    assert results == [i * i for i in range(12)]
    assert [str(w.message) for w in caught] == [f"item {i}" for i in range(12)]
    assert parallel_map(abs, [-2, 1, -3], jobs) == [2, 1, 3]


@pytest.mark.parametrize("jobs", [1, 2])
def test_a_failing_item_raises_at_its_turn_with_its_message(jobs):
    got = []
    with pytest.raises(MocapFormatError) as failure:
        for result in imap(_fails_at_three, range(10), jobs, window=4):
            got.append(result)
    assert got == [0, 1, 2]  # the results before it, none after
    assert str(failure.value) == "some/file.amc:7: item 3 is bad"
    assert multiprocessing.active_children() == []  # no worker left behind


def test_at_most_a_window_of_items_is_in_flight(tmp_path):
    """However fast the workers are, no more than `window` items beyond those consumed are handed out."""
    window, items = 3, [(os.fspath(tmp_path), i) for i in range(20)]
    for consumed, result in enumerate(imap(_note_start, items, 2, window=window), start=1):
        assert result == consumed - 1
        assert len(os.listdir(tmp_path)) <= consumed + window
    assert len(os.listdir(tmp_path)) == len(items)


def test_stopping_early_cancels_what_has_not_started(tmp_path):
    window, items = 2, [(os.fspath(tmp_path), i) for i in range(50)]
    results = imap(_note_start, items, 2, window=window)
    assert [next(results), next(results)] == [0, 1]
    results.close()  # waits for the items the workers hold, cancels the others
    assert len(os.listdir(tmp_path)) <= 2 + window
    assert multiprocessing.active_children() == []
