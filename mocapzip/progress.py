"""Progress bars on stderr, shown only to a person watching a terminal."""

from __future__ import annotations

import sys
from collections.abc import Iterator
from contextlib import contextmanager

from tqdm import tqdm

_QUIET = [False]  # no bars at all; set by `set_quiet` alone


def set_quiet(quiet: bool) -> None:
    """Show no progress bars from now on if `quiet` (the CLI's -q, JSON output, a bench child's job)."""
    _QUIET[0] = bool(quiet)


@contextmanager
def quieted(quiet: bool = True) -> Iterator[None]:
    """`set_quiet(quiet)` within the block, the setting before it restored after."""
    before = _QUIET[0]
    set_quiet(quiet)
    try:
        yield
    finally:
        set_quiet(before)


class _Bar(tqdm):
    """tqdm without its monitor thread (it only retunes a stalled bar's refresh): worker processes
    are forked (`mocapzip.parallel`), and forking a process that runs a second thread risks a
    deadlock in the child (Python 3.12 on warns of it on every fork)."""

    monitor_interval = 0


def progress(iterable=None, **kwargs):
    """tqdm over `iterable`, disabled when quiet or when stderr is not a terminal.

    Without an iterable, pass total=N and advance the bar with `.update(n)`: for work
    counted in something finer than the loop's items (frames, not classes).
    """
    return _Bar(iterable, disable=_QUIET[0] or not sys.stderr.isatty(), leave=False, **kwargs)
