"""Progress bars on stderr, shown only to a person watching a terminal."""

from __future__ import annotations

import sys

from tqdm import tqdm

QUIET = False  # set by the CLI's -q


def progress(iterable=None, **kwargs):
    """tqdm over `iterable`, disabled when quiet or when stderr is not a terminal.

    Without an iterable, pass total=N and advance the bar with `.update(n)`: for work
    counted in something finer than the loop's items (frames, not classes).
    """
    return tqdm(iterable, disable=QUIET or not sys.stderr.isatty(), leave=False, **kwargs)
