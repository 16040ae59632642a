"""Finding clips on disk: every clip file under the inputs (a suffix of an input format's,
`inputs.registry`), each paired with its skeleton: an AMC with an ASF, a BVH file with itself.

A clip whose format keeps its skeleton in a file of its own (an AMC, whose skeleton is an ASF)
pairs with the one the user names (`--asf`), or with the one in its own folder. A folder
may hold several: copies of one skeleton (CMU ships `07.asf` and `07-walk.asf`, which differ
only in line ends) count as one; different ones pair each AMC with the ASF whose name begins its
own (`07_01.amc` with `07.asf`), and a warning says so; an AMC that no name fits is ambiguous.
The pairing is decided here, once, so `inspect`, `compress` and `bench` agree on what a clip
is. Nothing is left out silently: a folder that cannot be listed is an error (or, with a
`skipped` list, a listed skip), and a named input that is not a regular file (a FIFO, a
device) is refused before anything opens it.
"""

from __future__ import annotations

import os
import warnings
from dataclasses import dataclass
from pathlib import Path

from mocapzip.formats.asf import read_asf_bytes
from mocapzip.formats.errors import MocapFormatError
from mocapzip.formats.text import check_regular_file
from mocapzip.inputs.registry import InputFormat, clip_format, clip_suffixes, input_formats


@dataclass(frozen=True)
class ClipSource:
    """One clip's motion file, its skeleton file, and the path it is stored under in an archive."""

    motion: Path  # the clip's file: an AMC, a BVH file
    skeleton: Path | None  # its skeleton's file: an ASF, or the clip's own file (BVH); None: not found
    relpath: str  # POSIX path relative to the input directory (or the bare file name)

    @property
    def format(self) -> InputFormat:
        """The clip's input format, by its file's suffix (`inputs.registry`)."""
        return clip_format(self.motion.name)


def _is_skeleton_file(name: str) -> bool:
    """Whether `name` is a skeleton file some format's clips pair with (an ASF)."""
    return any(f.skeleton_suffix and name.lower().endswith(f.skeleton_suffix) for f in input_formats())


def find_clips(inputs: list[str | os.PathLike], asf: str | os.PathLike | None = None,
               require_skeleton: bool = True, skipped: list | None = None) -> list[ClipSource]:
    """All clip files under `inputs` (directories are walked recursively), sorted by stored path.
    `asf`: the skeleton file of every clip whose format pairs with one (an AMC's ASF).

    Raises MocapFormatError for a missing input, a folder that cannot be listed, or (with
    `require_skeleton`) an AMC with no skeleton or an ambiguous one; without `require_skeleton`
    that AMC gets a warning and no skeleton. With a `skipped` list, such an AMC or folder is
    left out and recorded there instead (see `record_skip`).
    """
    forced = Path(asf) if asf is not None else None
    if forced is not None:
        if not forced.exists():
            raise MocapFormatError("skeleton file not found", forced)
        check_regular_file(forced.stat(), forced)
    clips: list[ClipSource] = []
    for item in inputs:
        path = Path(item)
        if path.is_dir():
            clips += _clips_under(path, skipped)
        elif path.is_file():
            if clip_format(path.name) is None:
                if _is_skeleton_file(path.name):
                    continue  # a skeleton named on the command line pairs by folder below
                raise MocapFormatError(f"not a clip (expected the {' or '.join(clip_suffixes())} extension)", path)
            clips.append(ClipSource(path, None, path.name))
        elif path.exists():  # before the link test: a link to a FIFO or a device is refused as one
            check_regular_file(path.stat(), path)  # a FIFO or a device: refused, never opened
        elif path.is_symlink():
            raise MocapFormatError("symbolic link loop or dangling symbolic link", path)
        else:
            raise MocapFormatError("no such file or directory", path)
    seen: dict[str, Path] = {}
    for clip in clips:
        if clip.relpath in seen:
            raise MocapFormatError(f"two inputs would be stored as '{clip.relpath}' (also {seen[clip.relpath]})",
                                   clip.motion)
        seen[clip.relpath] = clip.motion
    paired, folders = [], {}  # (folder, skeleton suffix) -> its skeleton files, grouped
    for c in clips:
        fmt = c.format
        if fmt.skeleton_suffix is None:  # the clip's file holds its skeleton
            paired.append(ClipSource(c.motion, c.motion, c.relpath))
            continue
        try:
            where = (c.motion.parent, fmt.skeleton_suffix)
            if forced is None and where not in folders:
                folders[where] = _skeletons_in_folder(*where)
            skeleton = forced or _skeleton_of(c.motion, folders[where], require_skeleton)
            paired.append(ClipSource(c.motion, skeleton, c.relpath))
        except MocapFormatError as exc:
            if skipped is None:
                raise
            record_skip(skipped, c, exc)
    for (folder, suffix), groups in folders.items():
        if len(groups) > 1:
            _say_pairings(folder, suffix, groups, [c for c in paired if c.motion.parent == folder])
    return sorted(paired, key=lambda c: c.relpath)


def _clips_under(top: Path, skipped: list | None) -> list[ClipSource]:
    """Every clip file under folder `top`, stored relative to it. A folder that cannot be listed
    raises MocapFormatError or, with a `skipped` list, is recorded there under its path."""

    def unlisted(error: OSError) -> None:
        folder = Path(error.filename or top)
        failure = MocapFormatError(f"cannot list this folder, its clips would be left out: {error.strerror}", folder)
        if skipped is None:
            raise failure
        _record(skipped, folder.relative_to(top).as_posix() if folder != top else os.fspath(top), failure)

    found = []
    for folder, dirs, files in os.walk(top, onerror=unlisted):
        dirs.sort()
        for name in sorted(files):
            if clip_format(name) is not None:
                motion = Path(folder) / name
                found.append(ClipSource(motion, None, motion.relative_to(top).as_posix()))
    return found


def no_clips(inputs) -> MocapFormatError:
    """The error for inputs that hold no clip."""
    return MocapFormatError(f"no clips found ({', '.join(clip_suffixes())})", ", ".join(map(os.fspath, inputs)))


def record_skip(skipped: list, clip: ClipSource, exc: Exception) -> None:
    """Add {"path": stored path, "error": one line} to `skipped` and say so in a warning."""
    _record(skipped, clip.relpath, exc)


def _record(skipped: list, relpath: str, exc: Exception) -> None:
    """`record_skip` for a clip or a folder stored (or not) under `relpath`."""
    error = f"{exc.filename}: {exc.strerror}" if isinstance(exc, OSError) and exc.filename else str(exc)
    skipped.append({"path": relpath, "error": error})
    warnings.warn(f"skipped {relpath}: {error}", stacklevel=4)


def _skeletons_in_folder(folder: Path, suffix: str) -> list[list[Path]]:
    """The folder's skeleton files (`suffix`: .asf) grouped by skeleton: files alike but for their
    line ends are one group. Any non-folder one counts, so that a FIFO or a dangling link is refused
    by name when read; one that cannot be read here stays a group of its own."""
    candidates = sorted(p for p in folder.iterdir() if p.name.lower().endswith(suffix) and not p.is_dir())
    if len(candidates) < 2:
        return [[p] for p in candidates]
    groups: dict[bytes | Path, list[Path]] = {}
    for path in candidates:
        try:
            key = read_asf_bytes(path).replace(b"\r\n", b"\n").replace(b"\r", b"\n")
        except (OSError, MocapFormatError):
            key = path
        groups.setdefault(key, []).append(path)
    return list(groups.values())


def _names_the_clip(skeleton: Path, motion: Path) -> bool:
    """Whether the skeleton file's name begins the clip's, up to a boundary: 07.asf names 07_01.amc
    and 07-walk.amc, not 070_01.amc."""
    stem, clip = skeleton.stem.lower(), motion.stem.lower()
    return clip.startswith(stem) and (len(clip) == len(stem) or not clip[len(stem)].isalnum())


def _skeleton_of(motion: Path, groups: list[list[Path]], required: bool) -> Path | None:
    """The folder's one skeleton, or the one with a file whose name begins the clip's (that file;
    of several, the longest name); the first of its copies where one skeleton has no such name."""
    fitting = [p for group in groups for p in group if _names_the_clip(p, motion)]
    if fitting:
        return max(fitting, key=lambda p: len(p.stem))
    if len(groups) == 1:
        return groups[0][0]
    if not groups:
        suffix = clip_format(motion.name).skeleton_suffix
        error = MocapFormatError(f"no skeleton: no {suffix} file in its folder (pass --asf FILE)", motion)
    else:
        names = ", ".join(p.name for group in groups for p in group)
        error = MocapFormatError(f"ambiguous skeleton: {len(groups)} different skeletons in its folder ({names}), "
                                 "none named like the clip; pass --asf FILE", motion)
    if required:
        raise error
    warnings.warn(str(error), stacklevel=4)
    return None


def _say_pairings(folder: Path, suffix: str, groups: list[list[Path]], clips: list[ClipSource]) -> None:
    """One warning for a folder of several different skeletons (files ending in `suffix`): which
    clips took which."""
    if not clips:
        return
    counts = {p: sum(1 for c in clips if c.skeleton == p) for group in groups for p in group}
    pairs = ", ".join(f"{p.name} ({n} clip{'' if n == 1 else 's'})" for p, n in counts.items() if n)
    kind = clips[0].format.name.upper()
    warnings.warn(f"{folder}: {len(groups)} different skeletons; each {kind} paired with the {suffix} whose "
                  f"name begins its own: {pairs}", stacklevel=3)
