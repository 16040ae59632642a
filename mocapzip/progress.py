"""Progress bars on stderr, shown only to a person watching a terminal."""

from __future__ import annotations

import sys

from tqdm import tqdm

QUIET = False  # set by the CLI's -q


def progress(iterable, **kwargs):
    """tqdm over `iterable`, disabled when quiet or when stderr is not a terminal."""
    return tqdm(iterable, disable=QUIET or not sys.stderr.isatty(), leave=False, **kwargs)
