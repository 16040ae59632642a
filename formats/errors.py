"""The one exception type every reader raises, so the CLI can print one line and exit 1, and
its kind for a damaged archive (`ArchiveError`)."""

from __future__ import annotations

import os


class MocapFormatError(Exception):
    """Bad input: names the file, the line (when there is one) and what was wrong.

    str(error) is "path:line: message" (parts that are unknown are left out).
    """

    def __init__(self, message: str, path: str | os.PathLike | None = None, line: int | None = None):
        super().__init__(message)
        self.message = message
        self.path = None if path is None else os.fspath(path)
        self.line = None if line is None else int(line)

    def __str__(self) -> str:
        where = [part for part in (self.path, None if self.line is None else str(self.line)) if part]
        return ": ".join([":".join(where), self.message]) if where else self.message

    def __repr__(self) -> str:
        return f"{type(self).__name__}({self.message!r}, path={self.path!r}, line={self.line!r})"

    def __reduce__(self):
        # Keep path and line when the error crosses a process boundary (multiprocessing).
        return (type(self), (self.message, self.path, self.line))


class ArchiveError(MocapFormatError):
    """A damaged or invalid archive; the message starts with the section: header, index or stream."""
