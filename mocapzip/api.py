"""mocapzip from Python (docs/api.md): open an archive and read its clips, compress and
decompress, read and write ASF/AMC files.

    import mocapzip
    with mocapzip.open("db.mcz") as archive:
        clip = archive["07/07_01.amc"]   # decodes this clip only
        clip.positions()                 # (frames, joints, 3) in cm

`mocapzip` re-exports every name in `__all__` and imports this module on first use, so
`import mocapzip` stays cheap. Errors: `MocapFormatError` for an input file that cannot be read
(it names the file and line), `ArchiveError` (a `MocapFormatError`) for a damaged or invalid
archive, `SettingsError` (a `ValueError`) for options an archive cannot hold.
"""

from __future__ import annotations

import os
from collections.abc import Iterable, Iterator
from functools import cached_property
from typing import NamedTuple

import numpy as np

from mocapzip.archive import reader, settings, writer
from mocapzip.archive.settings import SettingsError
from mocapzip.cli.choices import MAX_TO_MEAN  # the command line's default bound: both compress alike
from mocapzip.formats.amc import Motion, parse_amc, read_amc, write_amc
from mocapzip.formats.asf import Skeleton, parse_asf, read_asf, write_asf
from mocapzip.formats.errors import MocapFormatError
from mocapzip.formats.mcz import ArchiveError
from mocapzip.motion.kinematics import forward
from mocapzip.motion.skeleton import SkeletonModel

__all__ = ["ArchiveError", "Clip", "ClipError", "MocapArchive", "MocapFormatError", "SettingsError", "compress",
           "decompress", "open", "read_amc", "read_asf", "write_amc", "write_asf"]

class ClipError(NamedTuple):
    """How far a clip's joints are from its source, measured end to end through the AMC
    values `decompress` writes: the mean over joints and frames, the 99th percentile and the
    maximum, in cm. p99 is None in archives written before format 5."""

    mean_cm: float
    p99_cm: float | None
    max_cm: float


class Clip:
    """One clip of an open archive. Its motion is decoded on first use (only this clip's
    streams are read), then kept."""

    def __init__(self, archive: reader.Archive, index: int):
        self._archive, self.index = archive, index
        row = archive.clips[index]
        self.path: str = row["path"]
        self.frames: int = row["frames"]
        self.fps: float = archive.settings.fps
        self.error = ClipError(row["error_cm"], row.get("p99_error_cm"), row["max_error_cm"])

    def __repr__(self) -> str:
        return f"<Clip {self.path!r}: {self.frames} frames at {self.fps:g} fps, mean error {self.error.mean_cm:.3f} cm>"

    @cached_property
    def skeleton(self) -> Skeleton:
        """The clip's ASF skeleton, parsed (the file comes back byte for byte: `asf_text`)."""
        return parse_asf(self.asf_text.encode("latin-1"), self._archive.meta["skeletons"][self._skeleton]["name"])

    @property
    def asf_text(self) -> str:
        """The ASF file as it was compressed, one character per byte (Latin-1)."""
        return self._archive.skeleton_text(self._skeleton)

    @cached_property
    def motion(self) -> Motion:
        """The clip as the AMC file `decompress` writes, read back: bones, values, frame numbers."""
        data = self._archive.file_bytes("amc", self.index)
        return parse_amc(data, self.path, self.skeleton)

    @property
    def channels(self) -> np.ndarray:
        """(frames, channels) float64: the AMC values, bone after bone in `motion.bones` order."""
        return self.motion.values

    @cached_property
    def joint_names(self) -> tuple[str, ...]:
        """The joints of `positions()`: the root, then the end point of each bone."""
        return SkeletonModel.from_asf(self.skeleton).names

    def positions(self) -> np.ndarray:
        """(frames, joints, 3) float64 joint positions in cm, by forward kinematics of `channels`."""
        return forward(SkeletonModel.from_asf(self.skeleton), self.channels, self.motion).positions

    @property
    def _skeleton(self) -> int:
        return self._archive.clips[self.index]["skeleton"]


class MocapArchive:
    """An open .mcz archive: its clips in archive order, by index or by path. Use as a context
    manager (or call `close`)."""

    def __init__(self, path: str | os.PathLike):
        self._archive = reader.Archive(path)
        self.path = self._archive.path
        self._index = {row["path"]: i for i, row in enumerate(self._archive.clips)}

    @property
    def paths(self) -> list[str]:
        """Every clip's path (its AMC file's, relative to the compressed folder), in archive order."""
        return list(self._index)

    @property
    def settings(self) -> settings.Settings:
        """What the archive was compressed with (error target, bounds, representation...)."""
        return self._archive.settings

    def __len__(self) -> int:
        return len(self._index)

    def __iter__(self) -> Iterator[Clip]:
        return (Clip(self._archive, i) for i in range(len(self)))

    def __contains__(self, path: object) -> bool:
        return path in self._index

    def __getitem__(self, key: str | int) -> Clip:
        """The clip with this path, or at this index (negative counts from the end)."""
        if isinstance(key, str):
            if key not in self._index:
                raise KeyError(f"no clip {key!r} in {self.path}")
            return Clip(self._archive, self._index[key])
        if isinstance(key, (int, np.integer)) and not isinstance(key, bool):
            return Clip(self._archive, range(len(self))[key])
        raise TypeError(f"clips are indexed by path (str) or position (int), not {type(key).__name__}")

    def verify(self, jobs: int = 1) -> None:
        """Decode every clip and check every checksum, as `mcz test` (ArchiveError if one fails)."""
        self._archive.verify(jobs)

    def close(self) -> None:
        self._archive._reader.close()

    def __enter__(self) -> MocapArchive:
        return self

    def __exit__(self, *exc_info: object) -> None:
        self.close()

    def __repr__(self) -> str:
        return f"<MocapArchive {self.path!r}: {len(self)} clips>"


def open(path: str | os.PathLike) -> MocapArchive:  # noqa: A001 (mocapzip.open, as gzip.open)
    """Open the archive at `path` for reading: checks its header, index and meta, reads no clip."""
    return MocapArchive(path)


def compress(inputs: str | os.PathLike | Iterable[str | os.PathLike], output: str | os.PathLike, *,
             error: float = settings.DEFAULT_ERROR_CM, max_error: float | str | None = "default",
             contact_error: float | None = None, lossless: bool = False, classes: str = "pooled",
             jobs: int = 1, force: bool = False, **options) -> dict:
    """Compress the ASF/AMC files under `inputs` (folders or files) into the archive `output`, as
    `mcz compress` does; return its summary (clips, frames, bytes, achieved errors).

    `error`: each clip's mean joint error bound in cm. `max_error`: the bound on every joint of every
    frame, in cm ("default": 10 x `error`, as the command line; None: no bound). `contact_error`: the
    bound on planted foot joints. Other `options` are `Settings` fields (e.g. representation="positions").
    An existing `output` is replaced only with `force`.
    """
    if isinstance(inputs, (str, os.PathLike)):
        inputs = [inputs]
    bound = MAX_TO_MEAN * error if max_error == "default" else max_error
    chosen = settings.Settings(error_cm=error, max_error_cm=None if lossless else bound,
                               contact_error_cm=None if lossless else contact_error, lossless=lossless,
                               classes=classes, **options)
    return writer.compress([os.fspath(p) for p in inputs], output, chosen, force=force, jobs=jobs)


def decompress(archive: str | os.PathLike, output: str | os.PathLike, clips: Iterable[str] = (), *,
               force: bool = False, jobs: int = 1) -> dict:
    """Write the ASF and AMC files of the archive's clips under the folder `output`, as
    `mcz decompress` does: all clips, or those whose path matches one of the `clips` patterns
    (shell-style, e.g. "07/*"). Existing files are replaced only with `force`."""
    return reader.decompress(archive, output, tuple(clips), force=force, jobs=jobs)
