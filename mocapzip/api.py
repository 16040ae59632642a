"""mocapzip from Python (docs/api.md): open an archive and read its clips, compress and
decompress, read and write ASF/AMC and BVH files.

    import mocapzip
    with mocapzip.open("db.mcz") as archive:
        clip = archive["07/07_01.amc"]   # decodes this clip only
        clip.positions()                 # (frames, joints, 3) in cm

`mocapzip` re-exports these names and imports this module on first use, so `import mocapzip`
stays cheap (and changes nothing in the process: no environment variable, no exception hook).
Errors: `MocapFormatError` for an input file that cannot be read (it names the file and line),
`ArchiveError` (a `MocapFormatError`) for a damaged or invalid archive, `SettingsError` (a
`ValueError`) for options an archive cannot hold. An open archive is for one thread at a time.
"""

from __future__ import annotations

import numbers
import os
from collections.abc import Iterable, Iterator
from contextlib import nullcontext
from functools import cached_property
from typing import NamedTuple

import numpy as np

from mocapzip.archive import reader, settings, writer
from mocapzip.archive.settings import SettingsError
from mocapzip.defaults import ACL_SHELL_CM, MAX_TO_MEAN
from mocapzip.formats.amc import Motion, parse_amc, read_amc, write_amc
from mocapzip.formats.asf import Skeleton, read_asf, write_asf
from mocapzip.formats.bvh import Bvh, BvhJoint, parse_bvh, read_bvh, write_bvh
from mocapzip.formats.errors import MocapFormatError
from mocapzip.formats.mcz import ArchiveError
from mocapzip.motion.bvh_skeleton import file_positions, point_names
from mocapzip.inputs.registry import ClipApi, input_formats
from mocapzip.motion.kinematics import Pose, forward
from mocapzip.motion.metrics import ShellError, shell_errors
from mocapzip.motion.skeleton import SkeletonModel

__all__ = ["ArchiveError", "Bvh", "Clip", "ClipFidelity", "MocapArchive", "MocapFormatError", "SettingsError",
           "ShellError", "bvh_joint_positions", "bvh_point_names", "compress", "decompress", "joint_positions",
           "read_amc", "read_asf", "read_bvh", "write_amc", "write_asf", "write_bvh"]
# also `open`, left out of __all__ so that `from mocapzip import *` does not hide the built-in


class ClipFidelity(NamedTuple):
    """How far a clip's joints are from its source, measured end to end through the AMC
    values `decompress` writes, in cm: the mean over joints and frames, the 99th percentile of
    the frames' mean and the largest; and the worst shell vertex by ACL's metric
    (`vertex_cm`, vertices `settings.shell_cm` from each bone; docs/fidelity.md). All 0 for a
    lossless archive; p99 is None in lossy archives written before format 5, and vertex_cm
    before format 13, which did not store them."""

    mean_cm: float
    p99_cm: float | None
    max_cm: float
    vertex_cm: float | None = None


def joint_positions(skeleton: Skeleton, motion: Motion) -> np.ndarray:
    """(frames, joints, 3) float64 joint positions in cm of `motion` on `skeleton`, by forward
    kinematics: the root, then the end of every bone (the joints mcz's errors are measured on)."""
    return forward(SkeletonModel.from_asf(skeleton), motion.values, motion).positions


def bvh_joint_positions(bvh: Bvh, units: str | None = None) -> np.ndarray:
    """(frames, points, 3) float64 positions in cm of a BVH clip's joints and End Sites, in file
    order (`bvh_point_names`), as its channels put them (docs/bvh.md, Conventions). `units`: of its
    lengths ("cm", "mm", "m", "in"); None: inferred from the skeleton's size (MocapFormatError if
    it cannot be)."""
    return file_positions(bvh, units)


def bvh_point_names(bvh: Bvh) -> tuple[str, ...]:
    """What `bvh_joint_positions` gives, in order: each joint, then "<joint> End Site" if it has one."""
    return point_names(bvh.joints)


class Clip:
    """One clip of an open archive. Its motion is decoded on first use (only this clip's
    streams are read), then kept for as long as the clip is."""

    def __init__(self, archive: MocapArchive, index: int):
        self._owner, self.index = archive, index
        row = archive._archive.clips[index]
        self.path: str = row["path"]
        self.frames: int = row["frames"]
        # the rate the clip's files stated, else compress's --fps (default 120): ASF/AMC have no field for it
        self.fps: float = row.get("fps", archive._archive.settings.fps)
        # "amc" or "bvh": the kind of file the clip came from, which `decompress` writes (`inputs.registry`)
        self._format = archive._archive.clip_format(index)
        self.format: str = self._format.name
        self._entry = archive._archive.meta["skeletons"][row["skeleton"]]  # its skeleton's entry in meta
        lossless = archive._archive.settings.lossless
        self.error = ClipFidelity(row["error_cm"], 0.0 if lossless else row.get("p99_error_cm"), row["max_error_cm"],
                                  0.0 if lossless else row.get("max_vertex_error_cm"))

    def __repr__(self) -> str:
        return f"<Clip {self.path!r}: {self.frames} frames at {self.fps:g} fps, mean error {self.error.mean_cm:.3f} cm>"

    @cached_property
    def skeleton(self) -> Skeleton | list[BvhJoint]:
        """The clip's ASF skeleton, parsed (the file itself, byte for byte: `asf_text`); for a BVH
        clip, its joints (`bvh.joints`)."""
        return self._api.skeleton(self, self._entry)

    @cached_property
    def asf_text(self) -> str:
        """The ASF file as it was compressed, one character per byte (Latin-1); a BVH clip has none."""
        self._only("amc", "asf_text")
        return self._archive.skeleton_text(self._skeleton)

    @cached_property
    def motion(self) -> Motion:
        """The clip as the AMC file `decompress` writes, read back: bones, counts, values (read-only);
        a BVH clip's is `bvh`."""
        self._only("amc", "motion")
        motion = parse_amc(self._archive.file_bytes("motion", self.index), self.path, self.skeleton)
        motion.values.flags.writeable = False  # positions() are computed from them
        return motion

    @cached_property
    def bvh(self) -> Bvh:
        """A BVH clip as the file `decompress` writes, read back (values read-only)."""
        self._only("bvh", "bvh")
        try:
            return parse_bvh(self._archive.file_bytes("motion", self.index), self.path)
        except MocapFormatError as exc:  # the text the archive makes: a damaged archive, not a bad input
            raise ArchiveError(f"clip {self.path}: damaged ({exc})", self._archive.path) from exc

    @property
    def channels(self) -> np.ndarray:
        """(frames, values) float64, read-only: the AMC values, bone after bone in `motion.bones`
        order; a BVH clip's frame values, in the order of its joints' CHANNELS."""
        return getattr(self, self._api.file).values

    @cached_property
    def joint_names(self) -> tuple[str, ...]:
        """The joints of `positions()`: the root, then the end of every bone (BVH: every joint and
        End Site, in file order: `bvh_point_names`)."""
        return self._api.joint_names(self)

    def positions(self) -> np.ndarray:
        """(frames, joints, 3) float64 joint positions in cm (`joint_positions` of this clip;
        BVH: `bvh_joint_positions`, in the archive's units)."""
        return self._api.positions(self, self._entry)

    def shell_error(self, source: str | os.PathLike | Motion | Bvh, shell_cm: float = ACL_SHELL_CM) -> ShellError:
        """ACL's error of this clip against its `source` (docs/acl.md): per frame and bone, the
        worst of three virtual vertices `shell_cm` from the bone along its axes, in object space, in
        cm (`worst`, `per_bone`, `per_frame`, `worst_bone`, `worst_frame`; the bones in `names`). It
        sees what `error` does not: an end bone's twist, which moves no joint. `source`: the file
        the clip was compressed from (an AMC is read against this clip's ASF, the one it was
        compressed with), or that file already read (a `Motion`, a `Bvh`). MocapFormatError if it
        cannot be read, or is not this clip's (its frames or joints differ)."""
        if isinstance(source, (str, os.PathLike)):
            source = self._api.read_source(self, source)
        model, decoded = self._posed(getattr(self, self._api.file))
        _, original = self._posed(source)
        (frames, joints), (own_frames, own_joints) = original.positions.shape[:2], decoded.positions.shape[:2]
        if (frames, joints) != (own_frames, own_joints):
            raise MocapFormatError(f"{frames} frames of {joints} joints, the archive's {self.path} has {own_frames} "
                                   f"of {own_joints}: not its source", source.path)
        return shell_errors(model, original, decoded, shell_cm)

    def _posed(self, clip_file: Motion | Bvh) -> tuple[SkeletonModel, Pose]:
        """The model of this clip's skeleton and `clip_file` posed on it by forward kinematics (a
        BVH file's lengths in the archive's units)."""
        api = next(f.api for f in input_formats() if f.api is not None and isinstance(clip_file, f.api.file_type))
        model, motion = api.posed(self, clip_file, self._entry)
        return model, forward(model, motion.values, motion)

    def _only(self, kind: str, what: str) -> None:
        if self.format != kind:
            raise AttributeError(f"{self.path} is a {self.format.upper()} clip: it has no {what}")

    @property
    def _api(self) -> ClipApi:
        """How this clip's format is read here (`InputFormat.api`)."""
        if self._format.api is None:
            raise AttributeError(f"{self.path} is a {self.format.upper()} clip, which the API does not read")
        return self._format.api

    @property
    def _archive(self) -> reader.Archive:
        return self._owner._open_archive()

    @property
    def _skeleton(self) -> int:
        return self._archive.clips[self.index]["skeleton"]


class MocapArchive:
    """An open .mcz archive: its clips in archive order, by index or by path, each decoded once,
    when first asked for. Use as a context manager (or call `close`)."""

    def __init__(self, path: str | os.PathLike):
        self._archive: reader.Archive | None = reader.Archive(path)
        self.path = self._archive.path
        self._index = {row["path"]: i for i, row in enumerate(self._archive.clips)}
        self._clips: dict[int, Clip] = {}

    def _open_archive(self) -> reader.Archive:
        if self._archive is None:
            raise ValueError(f"I/O operation on a closed archive ({self.path})")
        return self._archive

    @property
    def paths(self) -> list[str]:
        """Every clip's path (its AMC file's, relative to the compressed folder), in archive order."""
        return list(self._index)

    @property
    def settings(self) -> settings.Settings:
        """What the archive was compressed with (error target, bounds, representation, fps...)."""
        return self._open_archive().settings

    def __len__(self) -> int:
        return len(self._index)

    def __iter__(self) -> Iterator[Clip]:
        return (self[i] for i in range(len(self)))

    def __contains__(self, path: object) -> bool:
        return path in self._index

    def __getitem__(self, key: str | int) -> Clip:
        """The clip with this path, or at this position (negative counts from the end)."""
        if isinstance(key, str):
            if key not in self._index:
                raise KeyError(f"no clip {key!r} in {self.path}")
            index = self._index[key]
        elif isinstance(key, numbers.Integral) and not isinstance(key, bool):
            index = range(len(self))[key]
        else:
            raise TypeError(f"clips are indexed by path (str) or position (int), not {type(key).__name__}")
        self._open_archive()
        if index not in self._clips:
            self._clips[index] = Clip(self, index)
        return self._clips[index]

    def verify(self, jobs: int = 1) -> None:
        """Decode every clip and check every checksum, as `mcz test` (ArchiveError if one fails)."""
        self._open_archive().verify(jobs)

    def close(self) -> None:
        """Close the file. Clips already decoded keep their data; decoding another raises ValueError."""
        if self._archive is not None:
            self._archive.__exit__(None, None, None)
            self._archive = None

    def __enter__(self) -> MocapArchive:
        return self

    def __exit__(self, *exc_info: object) -> None:
        self.close()

    def __repr__(self) -> str:
        state = "closed, " if self._archive is None else ""
        return f"<MocapArchive {self.path!r}: {state}{len(self)} clips>"


def open(path: str | os.PathLike) -> MocapArchive:  # noqa: A001 (mocapzip.open, as gzip.open)
    """Open the archive at `path` for reading: checks its header, index and meta, decodes no clip."""
    return MocapArchive(path)


_DEFAULT = object()  # max_error not given: the command line's default, MAX_TO_MEAN x error
# Settings fields that compress's own keywords set: given through **options they would conflict
_KEYWORD_FIELDS = {"error_cm": "error", "max_error_cm": "max_error", "contact_error_cm": "contact_error",
                   "vertex_error_cm": "max_vertex_error", "lossless": "lossless", "classes": "classes"}


def compress(inputs: str | os.PathLike | Iterable[str | os.PathLike], output: str | os.PathLike, *,
             error: float = settings.DEFAULT_ERROR_CM, max_error: float | None = _DEFAULT,
             contact_error: float | None = None, max_vertex_error: float | None = None, lossless: bool = False,
             classes: str = "pooled",
             asf: str | os.PathLike | None = None, units: str | None = None, skip_bad: bool = False, jobs: int = 1,
             dask: str | None = None, force: bool = False, **options) -> dict:
    """Compress the ASF/AMC and BVH files under `inputs` (folders or files) into the archive `output`, as
    `mcz compress` does (one worker process unless `jobs` says more); return its summary: clips,
    frames, bytes, achieved errors.

    `error`: each clip's mean joint error bound in cm. `max_error`: the bound on every joint of
    every frame in cm (not given: 10 x `error`, as the command line; None: no bound).
    `contact_error`: the bound on planted foot joints. `max_vertex_error`: the bound on every shell
    vertex of every frame, ACL's metric (`shell_cm=` sets their distance from the bone, 3 by
    default; docs/fidelity.md). `lossless`: every AMC value back exactly
    (then no error or bound may be given). `asf`: the skeleton of AMC files that have none beside
    them; `units`: of BVH files' lengths ("cm", "mm", "m", "in"; None: inferred from the skeleton's
    size); `skip_bad`: leave out clips that cannot be read, or coded within the bounds, listed in the
    summary. `dask`: run the work on a Dask cluster instead of `jobs` local workers, as `--dask` (a
    scheduler's address, or "local:N"; docs/cluster.md; a script that starts a local one needs
    `if __name__ == "__main__":`).
    Other keywords
    are fields of `mocapzip.archive.Settings` (representation="positions", ...); `fps=60` sets every
    clip's frame rate, as `--fps` (by default a clip takes the rate its files state, else 120). An
    existing `output` is replaced only with `force`.
    """
    if "fps" in options:  # as `--fps`: every clip at this rate, whatever its files state
        options.setdefault("fps_from_files", False)
    clashing = sorted(set(options) & set(_KEYWORD_FIELDS))
    if clashing:
        raise SettingsError(f"give {clashing[0]} as {_KEYWORD_FIELDS[clashing[0]]}=")
    for name, bound in (("max_error", max_error), ("contact_error", contact_error),
                        ("max_vertex_error", max_vertex_error)):
        if bound is not None and bound is not _DEFAULT and not isinstance(bound, numbers.Real):
            raise SettingsError(f"{name} must be a number of cm or None, not {bound!r}")
    if lossless:
        given = [name for name, value in (("error", error != settings.DEFAULT_ERROR_CM),
                                          ("max_error", max_error is not _DEFAULT), ("contact_error", contact_error),
                                          ("max_vertex_error", max_vertex_error is not None))
                 if value]
        if given:
            raise SettingsError(f"{given[0]} has no meaning with lossless=True (it stores every AMC value exactly)")
        max_error = None
    elif max_error is _DEFAULT:
        max_error = MAX_TO_MEAN * error
    try:
        chosen = settings.Settings(error_cm=error, max_error_cm=max_error, contact_error_cm=contact_error,
                                   vertex_error_cm=max_vertex_error, lossless=lossless, classes=classes, **options)
    except TypeError as exc:  # a keyword that is no Settings field
        raise SettingsError(f"compress() takes no option {str(exc).rsplit(' ', 1)[-1]}") from None
    inputs = [inputs] if isinstance(inputs, (str, os.PathLike)) else list(inputs)
    if dask is not None:  # Dask's module only when asked for: it is an optional extra
        from mocapzip.cluster import on_cluster
    with nullcontext() if dask is None else on_cluster(dask) as cluster:
        return writer.compress([os.fspath(p) for p in inputs], output, chosen, asf=asf, force=force,
                               jobs=jobs if cluster is None else cluster.workers, skip_bad=skip_bad, units=units)


def decompress(archive: str | os.PathLike, output: str | os.PathLike, clips: Iterable[str] = (), *,
               force: bool = False, jobs: int = 1) -> dict:
    """Write the ASF and AMC (and BVH) files of the archive's clips under the folder `output`, as
    `mcz decompress` does (on one thread unless `jobs` says more; worker processes for a lossless
    archive): all clips, or those
    whose path matches one of the `clips` patterns (shell-style, e.g. "07/*"). Existing files
    are replaced only with `force`."""
    return reader.decompress(archive, output, tuple(clips), force=force, jobs=jobs)
