"""The one exception type every reader raises, so the CLI can print one line and exit 1."""

from __future__ import annotations

import os


class MocapFormatError(Exception):
    """Bad input: names the file, the line (when there is one) and what was wrong."""

    def __init__(self, message: str, path: str | os.PathLike | None = None, line: int | None = None):
        super().__init__(message)
        self.message = message
        self.path = None if path is None else os.fspath(path)
        self.line = line

    def __str__(self) -> str:
        where = [part for part in (self.path, None if self.line is None else str(self.line)) if part]
        return ": ".join([":".join(where), self.message]) if where else self.message
