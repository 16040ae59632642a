"""Shared text handling for the Acclaim readers: decoding and number parsing with clear errors."""

from __future__ import annotations

import math

from .errors import MocapFormatError


def decode_text(data: bytes, path: str | None) -> str:
    """Decode an Acclaim file; refuse binary and UTF-16 content instead of parsing garbage.

    Acclaim files are ASCII in practice, but real ones carry Latin-1 bytes in comments
    (HDM05: 'f\\xfcr Bonn'), so anything that is not UTF-8 is read as Latin-1.
    """
    if not data.strip():
        raise MocapFormatError("empty file", path)
    if data[:2] in (b"\xff\xfe", b"\xfe\xff") or data[:4096].count(b"\x00") > 0:
        kind = "UTF-16 text" if data[:2] in (b"\xff\xfe", b"\xfe\xff") or data[1:4096:2].count(b"\x00") > 8 else "binary data"
        raise MocapFormatError(f"{kind}, not an ASCII Acclaim file", path)
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError:
        return data.decode("latin-1")


def number(word: str, path: str | None, line: int) -> float:
    """A finite float, or MocapFormatError naming file and line."""
    try:
        value = float(word)
    except ValueError:
        raise MocapFormatError(f"not a number: {word[:40]!r}", path, line) from None
    if not math.isfinite(value):
        raise MocapFormatError(f"value is not finite: {word!r}", path, line)
    return value
