"""Progress bars on stderr, shown only to a person watching a terminal."""

from __future__ import annotations

import sys

from tqdm import tqdm

QUIET = False  # set by the CLI's -q


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
    return _Bar(iterable, disable=QUIET or not sys.stderr.isatty(), leave=False, **kwargs)
