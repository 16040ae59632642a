"""Shared text handling for the text readers (ASF, AMC, BVH): decoding, line splitting and number parsing.

Numbers follow one grammar everywhere (ASF, AMC, BVH, fast and exact paths)::

    [+-]? ( digits [. digits?] | . digits ) ( [eE] [+-]? digits )?

so ``nan``, ``inf``, ``1_000`` or ``0x10`` are refused even though Python's ``float`` takes
some of them. Values must be finite and at most `MAX_ABS_VALUE` in magnitude: motion
capture angles and positions are far below 1e9, and a value like 1e308 is a corrupted file,
not a pose (it would also overflow every later computation).

AMC and BVH files convert their many numbers in compiled code (`numbers_compiled`), with the same
grammar and the same results as `number` here.
"""

from __future__ import annotations

import io
import os
import re
import secrets
import stat
from pathlib import Path

import numpy as np

from mocapzip.formats.errors import MocapFormatError

MAX_ABS_VALUE = 1e9
"""Largest accepted magnitude of any number in an ASF or AMC file (limits may be +-inf)."""


VALUES_PER_BLOCK = 1 << 18
"""Values a writer turns into text at once (whole frames, at least one): a clip's file is made in
blocks of about 3 MB (CMU: 4,228 frames), so that a clip at the size limits (100 MB of AMC text)
is never a single string, nor one being made (`amc.amc_blocks`, `bvh.BvhStyle.blocks`)."""


def in_value_range(values, bound: float = MAX_ABS_VALUE) -> bool:
    """Whether every one of `values` is a number a reader takes back: not NaN, within +-`bound`.
    Their largest and smallest say it (a NaN is both), with no temporary array of their size."""
    return bool(np.max(values, initial=-np.inf) <= bound and np.min(values, initial=np.inf) >= -bound)

NUMBER = re.compile(rb"[+-]?(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?\Z")
WHITESPACE = b" \t\r\n\x0b\x0c"  # what bytes.split() splits on
_UTF16_BOMS = (b"\xff\xfe", b"\xfe\xff")
_UTF8_BOM = b"\xef\xbb\xbf"


# --------------------------------------------------------------------------- opening

_KINDS = {stat.S_IFIFO: "a named pipe (FIFO)", stat.S_IFCHR: "a character device", stat.S_IFBLK: "a block device",
          stat.S_IFSOCK: "a socket", stat.S_IFDIR: "a directory"}


def check_regular_file(st: os.stat_result, path) -> None:
    """MocapFormatError unless `st` (of `path`) is a regular file: a pipe would block a reader
    and a device (/dev/zero) never ends, so input files must be plain files."""
    if not stat.S_ISREG(st.st_mode):
        kind = _KINDS.get(stat.S_IFMT(st.st_mode), "a special file")
        target = os.path.realpath(path)
        if target != os.path.abspath(path):
            kind += f" ({target})"
        raise MocapFormatError(f"not a regular file: {kind}", path)


def read_regular_file(path, most: int, what: str) -> bytes:
    """The bytes of `path`, opened by `open_regular_file`; MocapFormatError, before a byte is read,
    if it is larger than `most` bytes (`what` it is, for the message): a sparse file of no disk
    space can claim gigabytes, and the read would take that much memory."""
    with open_regular_file(path) as file:
        check_size(os.fstat(file.fileno()).st_size, most, what, path)
        data = file.read(most + 1)  # the file may have grown since
    check_size(len(data), most, what, path)
    return data


def check_size(size: int, most: int, what: str, path) -> None:
    """MocapFormatError if a file of `size` bytes is larger than `most`, the most `what` may have."""
    if size > most:
        raise MocapFormatError(f"file of {size:,} bytes is larger than the {most:,} bytes {what} may have", path)


def open_regular_file(path) -> io.BufferedReader:
    """`path` opened for binary reading; MocapFormatError if it is not a regular file (a symbolic
    link to one is fine), OSError if it cannot be opened.

    The type is checked before opening, so opening never blocks on a FIFO, and again on the
    open descriptor (opened with O_NONBLOCK), in case the path was replaced in between.
    """
    check_regular_file(os.stat(path), path)
    fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK)
    try:
        check_regular_file(os.fstat(fd), path)
        return os.fdopen(fd, "rb")
    except BaseException:
        os.close(fd)
        raise


def check_folders(folders) -> None:
    """MocapFormatError naming the first of `folders`, or of the folders above them, that exists but
    is no folder (a file, a symbolic link to nothing): no file can be written under it, and it is
    not what -f/--force replaces. Checked before any file is written."""
    for folder in sorted({Path(f) for f in folders}):
        for path in (folder, *folder.parents):
            if os.path.lexists(path) and not os.path.isdir(path):
                kind = "a symbolic link to nothing" if os.path.islink(path) else "a file"
                raise MocapFormatError(f"not a folder but {kind}: files cannot be written under it", path)


def check_not_folders(paths) -> None:
    """MocapFormatError naming the first of `paths`, files to be written, that is a folder: no file
    can be renamed over it, and it is not what -f/--force replaces. Checked before any file is written."""
    for path in paths:
        if os.path.isdir(path) and not os.path.islink(path):
            raise MocapFormatError("is a folder: a file cannot be written in its place (-f replaces files, not "
                                   "folders)", path)


def check_inside(root, paths) -> None:
    """MocapFormatError naming the first of `paths` whose folder resolves outside the folder `root`
    through a symbolic link already there (`root` itself may be one): a link planted in an output
    folder would take the files written under it anywhere on disk. Checked before any file is written."""
    top = os.path.realpath(root)
    for path in paths:
        if os.path.commonpath([top, os.path.realpath(Path(path).parent)]) != top:
            raise MocapFormatError("its folder leads outside the output folder through a symbolic link; "
                                   "refusing to write it", path)


def write_file_atomically(path: Path, *blocks: bytes) -> None:
    """A new file of `blocks` under a random name, created exclusively (never through a link planted
    there), then renamed over `path`: an interrupted run never leaves half a file behind; an error names `path`."""
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f".mcz-{secrets.token_hex(8)}.tmp")
    try:
        fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL | getattr(os, "O_NOFOLLOW", 0), 0o666)
    except OSError as exc:
        raise OSError(exc.errno, os.strerror(exc.errno), os.fspath(path)) from exc
    try:
        try:
            for block in blocks:
                view = memoryview(block)
                while view:
                    view = view[os.write(fd, view):]
        finally:
            os.close(fd)
        os.replace(tmp, path)
    except BaseException as exc:
        tmp.unlink(missing_ok=True)
        if isinstance(exc, OSError) and exc.errno and exc.filename != os.fspath(path):  # a full disk: name the file
            raise OSError(exc.errno, os.strerror(exc.errno), os.fspath(path)) from exc
        raise


# --------------------------------------------------------------------------- decoding


def check_text(data: bytes, path: str | None, what: str = "an ASCII Acclaim file") -> bytes:
    """`data` without a UTF-8 byte-order mark; MocapFormatError for empty, UTF-16 or binary input
    (`what` the file should have been, for the message)."""
    if not isinstance(data, (bytes, bytearray, memoryview)):
        raise TypeError(f"expected bytes, got {type(data).__name__}")
    data = bytes(data)
    if data.startswith(_UTF8_BOM):
        data = data[len(_UTF8_BOM):]
    if data[:2] in _UTF16_BOMS:
        raise MocapFormatError(f"UTF-16 text, not {what}", path, 1)
    head = data[:65536]
    if b"\x00" in head:
        # ASCII stored as UTF-16 without a byte-order mark: every other byte is NUL, the others not
        # (text followed by NULs, as a disk full or a sparse file leaves it, has NULs at both)
        utf16 = (head[1::2].count(0) > len(head) // 4) != (head[0::2].count(0) > len(head) // 4)
        kind = "UTF-16 text" if utf16 else "binary data (NUL bytes)"
        raise MocapFormatError(f"{kind}, not {what}", path, line_of_offset(data, data.index(b"\x00")))
    if not data or data.isspace():  # (strip() would copy the file)
        raise MocapFormatError("empty file", path, 1)
    return data


def detect_encoding(data: bytes) -> str:
    """'utf-8' when `data` is valid UTF-8 (ASCII included), else 'latin-1'.

    Acclaim files are ASCII in practice, but real ones carry Latin-1 bytes in comments
    (HDM05: 'f\\xfcr Bonn'); Latin-1 decodes any byte, so reading never fails on them.
    """
    try:
        data.decode("utf-8")
    except UnicodeDecodeError:
        return "latin-1"
    return "utf-8"


def decode_text(data: bytes, path: str | None) -> str:
    """Checked (see `check_text`) and decoded text of an Acclaim file."""
    data = check_text(data, path)
    return data.decode(detect_encoding(data))


def split_lines(text):
    """Lines of `text` (str or bytes) without their endings; CRLF, LF and CR all end a line.

    Unlike str.splitlines this never splits on form feeds, U+0085 or U+2028, so line
    numbers agree with every text editor.
    """
    if isinstance(text, str):
        return text.replace("\r\n", "\n").replace("\r", "\n").split("\n")
    return text.replace(b"\r\n", b"\n").replace(b"\r", b"\n").split(b"\n")


def line_of_offset(data: bytes, offset: int) -> int:
    """1-based line number of byte `offset` (CRLF, LF and lone CR count as one line end each)."""
    head = data[:offset]
    return head.count(b"\n") + head.count(b"\r") - head.count(b"\r\n") + 1


# --------------------------------------------------------------------------- single numbers


def number(word, path: str | None, line: int | None, *, what: str = "value") -> float:
    """A finite float within MAX_ABS_VALUE, or MocapFormatError naming file and line."""
    raw = word.encode("latin-1", "replace") if isinstance(word, str) else bytes(word)
    if not NUMBER.match(raw):
        shown = word[:40] if isinstance(word, str) else raw[:40].decode("latin-1")  # as read: not '?' for each letter
        lowered = shown.lower().lstrip("+-")
        if lowered in ("nan", "inf", "infinity"):
            raise MocapFormatError(f"{what} is not finite: {shown!r}", path, line)
        raise MocapFormatError(f"not a number: {shown!r}", path, line)
    value = float(raw)
    if not abs(value) <= MAX_ABS_VALUE:
        shown = raw[:40].decode("latin-1") + ("..." if len(raw) > 40 else "")  # a word of any length: the line's
        raise MocapFormatError(f"{what} {shown} is out of range (|v| > {MAX_ABS_VALUE:g})", path, line)
    return value


def integer(word, path: str | None, line: int | None, *, what: str = "value") -> int:
    raw = word.encode("latin-1", "replace") if isinstance(word, str) else bytes(word)
    if not re.fullmatch(rb"[+-]?\d+", raw):
        raise MocapFormatError(f"{what} must be an integer, got {raw[:40].decode('latin-1')!r}", path, line)
    magnitude = whole_number(raw.lstrip(b"+-"), 10**18 - 1)
    if magnitude is None:
        raise MocapFormatError(f"{what} {raw[:40].decode('latin-1')} is out of range", path, line)
    return -magnitude if raw.startswith(b"-") else magnitude


def whole_number(word, at_most: int) -> int | None:
    """The value of `word` (str or bytes) when it is ASCII digits worth at most `at_most`, else None.
    Its length is checked before int() sees it: int() raises on more than 4,300 digits (leading
    zeros too, sys.get_int_max_str_digits), and a file's word may have any number."""
    raw = word.encode("latin-1", "replace") if isinstance(word, str) else bytes(word)
    if not re.fullmatch(rb"[0-9]+", raw):
        return None
    significant = raw.lstrip(b"0")
    if len(significant) > len(str(at_most)):
        return None
    value = int(significant or b"0")
    return value if value <= at_most else None


MAX_FRAME_RATE = 100_000.0  # frames per second: far above any capture system, below nonsense
# How exporters state a frame rate in a file that has no field for it: Vicon Blade's AMC header
# `# Frame Rate: 200.000 fps`, and `fps:30` / `fps = 30` in an ASF's :documentation.
_STATED_RATES = (re.compile(r"^#\s*frame\s*rate\s*[:=]\s*(\d+(?:\.\d*)?|\.\d+)\s*(?:fps|hz)?\s*$", re.IGNORECASE),
                 re.compile(r"^#?\s*fps\s*[:=]\s*(\d+(?:\.\d*)?|\.\d+)\s*$", re.IGNORECASE))
MIN_FRAME_RATE = 1.0  # frames per second: a stated rate below is no capture rate


def stated_frame_rate(lines) -> float | None:
    """The frame rate the first of `lines` that states one gives, in frames per second, or None.

    ASF and AMC have no field for it (readers assume one: 120 Hz for CMU), but exporters write
    it in a comment or the documentation, on a line of its own; a rate outside [MIN_FRAME_RATE,
    MAX_FRAME_RATE] is no rate."""
    for line in lines:
        for pattern in _STATED_RATES:
            match = pattern.search(line.strip())
            if match and MIN_FRAME_RATE <= float(match.group(1)) <= MAX_FRAME_RATE:
                return float(match.group(1))
    return None


def as_printed(values: np.ndarray, notation: str, digits: int) -> np.ndarray:
    """`values` as a writer prints them with `%.<digits><notation>` ("g" or "f") and a reader reads
    them back (`float('%.6g' % v)` of each), without the text: a decoded clip's values exactly as
    its file gives them, made in compiled code (`numbers_compiled.printed_values`); the rare value
    it leaves (an exact tie, beyond its ranges) is printed and read in Python."""
    from mocapzip.formats.numbers_compiled import printed_values

    values = np.ascontiguousarray(values, dtype=np.float64)
    out = np.empty_like(values)
    digits = int(digits) if notation == "f" else max(int(digits), 1)  # %.0g is %.1g
    if printed_values(values.ravel(), notation == "f", digits, out.ravel()):
        spec = f"%.{int(digits)}{notation}"
        for at in zip(*np.nonzero(np.isnan(out))):
            out[at] = float(spec % values[at])
    return out
