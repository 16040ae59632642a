"""mocapzip from Python (docs/api.md): open an archive and read its clips, compress and
decompress, remove and append clips, read and write ASF/AMC and BVH files.

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

import difflib
import errno
import functools
import numbers
import os
from collections.abc import Iterable, Iterator
from contextlib import nullcontext
from functools import cached_property
from pathlib import Path, PurePosixPath
from typing import NamedTuple

import numpy as np

from mocapzip.archive import reader, settings
from mocapzip.archive.settings import SettingsError
from mocapzip.defaults import ACL_SHELL_CM, BLAS_THREAD_VARIABLES, MAX_TO_MEAN
from mocapzip.convert import SAVE_CONVERSIONS
from mocapzip.formats.amc import Motion, read_amc, write_amc
from mocapzip.formats.asf import Skeleton, read_asf, write_asf
from mocapzip.formats.bvh import Bvh, BvhJoint, read_bvh, write_bvh
from mocapzip.formats.errors import MocapFormatError
from mocapzip.formats.mcz import ArchiveError
from mocapzip.formats.text import write_file_atomically
from mocapzip.inputs.registry import ClipApi, input_formats
from mocapzip.motion.bvh_skeleton import file_positions, point_names
from mocapzip.motion.kinematics import Pose, forward
from mocapzip.motion.metrics import ShellError, shell_errors
from mocapzip.motion.skeleton import SkeletonModel

__all__ = ["ArchiveError", "Bvh", "Clip", "ClipFidelity", "MocapArchive", "MocapFormatError", "SettingsError",
           "ShellError", "append", "bvh_joint_positions", "bvh_point_names", "compress", "decompress",
           "joint_positions", "read_amc", "read_asf", "read_bvh", "remove", "write_amc", "write_asf", "write_bvh"]
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


@functools.cache
def _blas_controller():
    """threadpoolctl's view of the BLAS libraries NumPy loaded, found once: finding them takes
    5 ms, as long as decoding a short clip."""
    from threadpoolctl import ThreadpoolController

    return ThreadpoolController()


def _one_blas_thread(function):
    """`function` run on one BLAS thread, as the command line runs (`parallel.one_blas_thread`):
    a clip's matrices are small, more threads only contend. An environment that sets a BLAS
    thread count (OPENBLAS_NUM_THREADS...) wins."""

    @functools.wraps(function)
    def limited(*args, **kwargs):
        if any(name in os.environ for name in BLAS_THREAD_VARIABLES):
            return function(*args, **kwargs)
        with _blas_controller().limit(limits=1):
            return function(*args, **kwargs)

    return limited


def _quaternions(rotations: np.ndarray) -> np.ndarray:
    """(..., 4) unit quaternions (w, x, y, z) of row-vector rotation matrices R (..., 3, 3): the
    quaternion q with q v q* = v R for a column vector v (that is, of the column matrix R^T)."""
    m = np.swapaxes(rotations, -1, -2)  # column convention
    trace = m[..., 0, 0] + m[..., 1, 1] + m[..., 2, 2]
    q = np.empty((*m.shape[:-2], 4))
    # the largest of w, x, y, z first: no division by a small number (Shepperd)
    cases = np.argmax(np.stack([trace, m[..., 0, 0], m[..., 1, 1], m[..., 2, 2]], axis=-1), axis=-1)
    for case in range(4):
        at = cases == case
        if not at.any():
            continue
        a = m[at]
        if case == 0:
            s = np.sqrt(1.0 + a[:, 0, 0] + a[:, 1, 1] + a[:, 2, 2]) * 2
            q[at] = np.stack([s / 4, (a[:, 2, 1] - a[:, 1, 2]) / s, (a[:, 0, 2] - a[:, 2, 0]) / s,
                              (a[:, 1, 0] - a[:, 0, 1]) / s], axis=-1)
        else:
            i, j, k = case - 1, case % 3, (case + 1) % 3
            s = np.sqrt(1.0 + a[:, i, i] - a[:, j, j] - a[:, k, k]) * 2
            parts = np.empty((len(a), 4))
            parts[:, 0] = (a[:, k, j] - a[:, j, k]) / s
            parts[:, 1 + i] = s / 4
            parts[:, 1 + j] = (a[:, j, i] + a[:, i, j]) / s
            parts[:, 1 + k] = (a[:, k, i] + a[:, i, k]) / s
            q[at] = parts
    return q


class Clip:
    """One clip of an open archive, or a range of its frames (`clip[a:b]`). Its motion is decoded
    on first use (only this clip's streams are read), then kept for as long as the clip is, and
    shared with its frame ranges."""

    def __init__(self, archive: MocapArchive, index: int, start: int = 0, stop: int | None = None,
                 whole: Clip | None = None):
        self._owner, self.index = archive, index
        row = self._row = archive._archive.clips[index]
        self.path: str = row["path"]
        self._start = start
        self._stop = row["frames"] if stop is None else stop
        self._whole = self if whole is None else whole  # the clip whose decoded values this range shares
        self.frames: int = self._stop - self._start
        # the rate the clip's files stated, else compress's --fps (default 120): ASF/AMC have no field for it
        self.fps: float = row.get("fps", archive._archive.settings.fps)
        # its input format's name: the kind of file it came from, which `decompress` writes (`inputs.registry`)
        self._format = archive._archive.clip_format(index)
        self.format: str = self._format.name
        self._entry = archive._archive.meta["skeletons"][row["skeleton"]]  # its skeleton's entry in meta
        lossless = archive._archive.settings.lossless
        self.error = ClipFidelity(row["error_cm"], 0.0 if lossless else row.get("p99_error_cm"), row["max_error_cm"],
                                  0.0 if lossless else row.get("max_vertex_error_cm"))

    def __repr__(self) -> str:
        frames = "" if self._whole is self else f" [{self._start}:{self._stop}]"
        return (f"<Clip {self.path!r}{frames}: {self.frames} frames at {self.fps:g} fps, "
                f"mean error {self.error.mean_cm:.3f} cm>")

    def __len__(self) -> int:
        return self.frames

    def __getitem__(self, frames: slice) -> Clip:
        """The frames `frames` (a slice with step 1, as a list's) of this clip: a clip whose arrays
        are that range, decoded once with the whole clip."""
        if not isinstance(frames, slice) or frames.step not in (None, 1):
            raise TypeError(f"a clip is sliced by frames, clip[a:b], not by {frames!r}")
        start, stop, _ = frames.indices(self.frames)
        return Clip(self._owner, self.index, self._start + start, self._start + max(start, stop), self._whole)

    @property
    def units(self) -> str | None:
        """The unit of the lengths in the clip's own skeleton as the archive stores it ("cm", "mm", "m",
        "in"; a BVH hierarchy's, given or inferred at compress), None where its skeleton entry has none."""
        return self._entry.get("units")

    @property
    def duration(self) -> float:
        """Seconds: `frames` / `fps`."""
        return self.frames / self.fps

    @property
    def skeleton(self) -> Skeleton | list[BvhJoint]:
        """The clip's ASF skeleton, parsed once per archive (the file itself, byte for byte:
        `asf_text`); for a BVH clip, its joints."""
        return self._api.skeleton(self._stored[0])

    @cached_property
    def asf_text(self) -> str:
        """The ASF file as it was compressed, one character per byte (Latin-1); a BVH clip has none."""
        self._only("asf_text")
        return self._whole._skeleton_text

    @cached_property
    def motion(self) -> Motion:
        """The clip as the AMC file `decompress` writes, read back: bones, counts, values (read-only);
        a BVH clip's is `bvh`."""
        return self._file("motion")

    @cached_property
    def bvh(self) -> Bvh:
        """A BVH clip as the file `decompress` writes (values read-only), made without its text: its
        header (hierarchy and MOTION lines) and `style` as stored, `format_bvh` of it that file."""
        return self._file("bvh")

    def _file(self, name: str) -> Motion | Bvh:
        """The clip's file (`ClipApi.file`, called `name` here), made without its text."""
        self._only(name)
        return self._api.make_file(self, self._row, self._start, self._whole._skeleton_text, self._entry)

    @cached_property
    def _skeleton_text(self) -> str:
        """The skeleton's text as stored, kept: a closed archive's clip still has it."""
        return self._archive.skeleton_text(self._skeleton)

    @cached_property
    def channels(self) -> np.ndarray:
        """(frames, values) float64, read-only: the values of the file `decompress` writes (made
        without its text: each as printed and read back). AMC: bone after bone in `motion.bones`
        order; BVH: in the order of its joints' CHANNELS. Named in `channel_labels`."""
        values = self._api.printed(self._row, self._whole._decoded[self._start : self._stop])
        values.flags.writeable = False  # positions() are computed from them
        return values

    def values(self, dtype=np.float64) -> np.ndarray:
        """`channels` as an array of `dtype` (float32 halves the memory)."""
        return self.channels.astype(dtype, copy=False)

    @cached_property
    def channel_labels(self) -> tuple[str, ...]:
        """What each column of `channels` holds, as "joint.dof", the dof as the file names it: AMC
        "lfemur.rx", "root.tx"; BVH "Hips.Xposition", "Hips.Zrotation"."""
        return self._api.labels(self._row, *self._stored)

    @cached_property
    @_one_blas_thread
    def _decoded(self) -> np.ndarray:
        """The whole clip's values in its file's channels, as decoded, before they are printed."""
        api = self._api  # a format the API does not read (`InputFormat.api`) is refused here, by name
        self._stored, self._skeleton_text  # kept with the values: a closed archive's clip still poses them
        return api.decoded(self._archive, self.index)

    @cached_property
    def joint_names(self) -> tuple[str, ...]:
        """The joints of `positions()`: the root, then the end of every bone (BVH: every joint and
        End Site, in file order: `bvh_point_names`)."""
        return self._api.joint_names(*self._stored)

    @cached_property
    @_one_blas_thread
    def _positions(self) -> np.ndarray:
        """(frames, joints, 3) float64 positions of `joint_names`."""
        return self._api.positions(self, self._stored[1], self._entry)

    @cached_property
    @_one_blas_thread
    def _rotations(self) -> np.ndarray:
        """(frames, joints, 3, 3) float64 world rotations of `joint_names`, on row vectors."""
        return self._api.rotations(self, self._stored[1], self._entry)

    @cached_property
    def _parents(self) -> np.ndarray:
        return self._api.parents(*self._stored)

    @property
    def parents(self) -> np.ndarray:
        """(joints,) the index in `joint_names` of each joint's parent, -1 for the root: the bones
        a stick figure draws, from each joint to its parent."""
        return self._parents.copy()

    def positions(self, dtype=np.float64) -> np.ndarray:
        """(frames, joints, 3) joint positions in cm (`joint_positions` of this clip; BVH:
        `bvh_joint_positions`, in the archive's units), as `dtype`."""
        return self._positions.astype(dtype)

    def rotations(self, dtype=np.float64, world: bool = False) -> np.ndarray:
        """(frames, joints, 4) unit quaternions (w, x, y, z) of `joint_names`' rotations, relative
        to the skeleton's rest pose: each joint's in its parent's frame (its local rotation), or in
        the world with `world=True`. A quaternion q turns a column vector v to q v q*."""
        turns = self._rotations
        if not world:
            parents = self._parents
            turns = turns.copy()
            has = parents >= 0
            turns[:, has] = turns[:, has] @ np.swapaxes(self._rotations[:, parents[has]], -1, -2)
        return _quaternions(turns).astype(dtype)

    def transforms(self, dtype=np.float64) -> np.ndarray:
        """(frames, joints, 4, 4) world transforms of `joint_names`: the world rotation (as
        `rotations(world=True)`, a matrix on column vectors) and the joint's position in cm as
        translation, so that T @ (v, 1) places a point v cm from the joint."""
        out = np.zeros((self.frames, len(self.joint_names), 4, 4))
        out[..., :3, :3] = np.swapaxes(self._rotations, -1, -2)
        out[..., :3, 3] = self._positions
        out[..., 3, 3] = 1.0
        return out.astype(dtype, copy=False)

    def save(self, path: str | os.PathLike, *, force: bool = False) -> list[str]:
        """Write the clip to `path` in the format its suffix names: its own (the file `decompress`
        writes, an AMC with its ASF beside it as <stem>.asf) or the other, converted as `mcz convert`
        does (AMC to BVH, BVH to AMC and ASF). Returns the files written; FileExistsError unless `force`."""
        api, own, target = self._api, self._format, Path(path)
        into = [f for f in input_formats() if f is own or (own, f) in SAVE_CONVERSIONS]
        saved_as = next((f for f in into if target.suffix.lower() in f.suffixes), None)
        if saved_as is None:
            raise ValueError(f"{target}: save writes {' or '.join(s for f in into for s in f.suffixes)} files, "
                             f"not {target.suffix or 'no suffix'}")
        names = [target, *([target.with_suffix(saved_as.skeleton_suffix)] if saved_as.skeleton_suffix else [])]
        existing = [p for p in names if os.path.lexists(p)]
        if existing and not force:
            raise FileExistsError(None, "already exists", os.fspath(existing[0]))
        if saved_as is own:
            files = api.own_files(self)
        else:
            files = SAVE_CONVERSIONS[own, saved_as](self, self._entry, [os.fspath(n) for n in names])
        for name, data in zip(names, files):
            write_file_atomically(name, data)
        return [os.fspath(n) for n in names]

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
        BVH file's lengths in the archive's units), as the format whose file it is says."""
        api = next((f.api for f in input_formats() if f.api is not None and isinstance(clip_file, f.api.file_type)),
                   self._api)
        model, motion = api.posed(self._stored[1], clip_file, self._entry)
        return model, forward(model, motion.values, motion)

    def _only(self, what: str) -> None:
        """AttributeError unless the clip's format has the attribute `what` (`ClipApi.file`, `also_has`)."""
        api = self._format.api
        if api is None or what not in (api.file, *api.also_has):
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
        return self._row["skeleton"]

    @cached_property
    def _stored(self) -> tuple:
        """(skeleton, model) of the clip's skeleton, read once per archive (`Archive.stored_skeleton`)."""
        return self._archive.stored_skeleton(self._skeleton)


class MocapArchive:
    """An open .mcz archive: a mapping of its clips' stored paths to clips, in archive order
    (`keys`, `values`, `items`, `get`, `in`, `len`; iterating gives the clips, as `values()`). A
    clip is found by its path, by its file's name where no other clip has it, or by position;
    `glob` finds clips by pattern. Each is decoded once, when first asked for. Use as a context
    manager (or call `close`)."""

    def __init__(self, path: str | os.PathLike):
        self._archive: reader.Archive | None = reader.Archive(path, lazy_skeletons=True)
        self.path = self._archive.path
        self._index = {row["path"]: i for i, row in enumerate(self._archive.clips)}
        by_name: dict[str, list[int]] = {}
        for stored, i in self._index.items():
            by_name.setdefault(PurePosixPath(stored).name, []).append(i)
        self._by_name = by_name
        self._clips: dict[int, Clip] = {}

    def _open_archive(self) -> reader.Archive:
        if self._archive is None:
            raise ValueError(f"I/O operation on a closed archive ({self.path})")
        return self._archive

    @property
    def paths(self) -> list[str]:
        """Every clip's path (its AMC file's, relative to the compressed folder), in archive order."""
        return list(self._index)

    def keys(self) -> list[str]:
        """The clips' stored paths, in archive order (`paths`)."""
        return self.paths

    def values(self) -> list[Clip]:
        """The clips, in archive order (none decoded yet)."""
        return [self[i] for i in range(len(self))]

    def items(self) -> list[tuple[str, Clip]]:
        """(path, clip) of every clip, in archive order."""
        return list(zip(self.paths, self.values()))

    def get(self, key: str, default=None):
        """`archive[key]`, or `default` where no clip matches."""
        try:
            return self[key]
        except KeyError:
            return default

    def glob(self, pattern: str) -> list[Clip]:
        """The clips whose stored path, or file name, matches the shell-style `pattern`
        ("09_*", "09/*", "*walk*"), in archive order (as `mcz decompress --clip`)."""
        return [self[i] for i, stored in enumerate(self._index) if reader.path_matches(stored, pattern)]

    @property
    def settings(self) -> settings.Settings:
        """What the archive was compressed with (error target, bounds, representation, fps...)."""
        return self._open_archive().settings

    def __len__(self) -> int:
        return len(self._index)

    def __iter__(self) -> Iterator[Clip]:
        return (self[i] for i in range(len(self)))

    def __contains__(self, path: object) -> bool:
        return isinstance(path, str) and (path in self._index or len(self._by_name.get(path, ())) == 1)

    def __getitem__(self, key: str | int) -> Clip:
        """The clip with this path (or file name, where only one clip has it), or at this position
        (negative counts from the end)."""
        if isinstance(key, str):
            index = self._index.get(key)
            if index is None:
                index = self._by_name_or_miss(key)
        elif isinstance(key, numbers.Integral) and not isinstance(key, bool):
            index = range(len(self))[key]
        else:
            raise TypeError(f"clips are indexed by path (str) or position (int), not {type(key).__name__}")
        self._open_archive()
        if index not in self._clips:
            self._clips[index] = Clip(self, index)
        return self._clips[index]

    def _by_name_or_miss(self, key: str) -> int:
        named = self._by_name.get(key, [])
        if len(named) == 1:
            return named[0]
        if named:
            raise KeyError(f"{len(named)} clips are called {key!r} in {self.path}: give its path "
                           f"({', '.join(self.paths[i] for i in named[:3])}{', ...' if len(named) > 3 else ''})")
        near = difflib.get_close_matches(key, [*self._index, *self._by_name], n=1)
        hint = f"; did you mean {near[0]!r}?" if near else ""
        raise KeyError(f"no clip {key!r} in {self.path}{hint}")

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
             classes: str = "pooled", asf: str | os.PathLike | None = None, units: str | None = None,
             skip_bad: bool = False, jobs: int | None = None, dask: str | None = None, force: bool = False,
             progress: bool = True, **options) -> dict:
    """Compress the ASF/AMC and BVH files under `inputs` (folders or files) into the archive `output`, as
    `mcz compress` does (a worker process per core unless `jobs` says otherwise; progress bars on
    a terminal unless `progress=False`); return its summary: clips,
    frames, bytes, achieved errors.

    `error`: each clip's mean joint error bound in cm. `max_error`: the bound on every joint of
    every frame in cm (not given: 5 x `error`, as the command line; None: no bound).
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
    are fields of `mocapzip.archive.Settings` (representation="positions", ...; its default "auto" picks
    by `error`, and the archive's settings name the one used); `fps=60` sets every
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
    if dask is not None:  # Dask's module only when asked for: it is an optional extra
        from mocapzip.cluster import on_cluster
    from mocapzip.archive import writer  # the encoder's modules only when compressing: open() is faster without

    with nullcontext() if dask is None else on_cluster(dask) as cluster, _bars(progress):
        return writer.compress(_input_paths(inputs), output, chosen, asf=asf, force=force,
                               jobs=_every_core(jobs) if cluster is None else cluster.workers, skip_bad=skip_bad,
                               units=units)


def _input_paths(inputs: str | os.PathLike | Iterable[str | os.PathLike]) -> list[str]:
    """`inputs` (one folder or file, or several) as the list of paths the command line passes."""
    return [os.fspath(p) for p in ([inputs] if isinstance(inputs, (str, os.PathLike)) else inputs)]


def _every_core(jobs: int | None) -> int:
    """`jobs`, or every core where not given, as the command line's -j."""
    return (os.cpu_count() or 1) if jobs is None else jobs


def _bars(shown: bool):
    """Progress bars as the command line's (`mocapzip.progress`: on a terminal only), or none."""
    from mocapzip import progress

    return nullcontext() if shown else progress.quieted()


def decompress(archive: str | os.PathLike, output: str | os.PathLike, clips: Iterable[str] = (), *,
               force: bool = False, jobs: int = 1) -> dict:
    """Write the ASF and AMC (and BVH) files of the archive's clips under the folder `output`, as
    `mcz decompress` does (on one thread unless `jobs` says more; worker processes for a lossless
    archive): all clips, or those whose path or file name matches one of the `clips` patterns
    (shell-style, e.g. "07/*", "07_0*"). Existing files are replaced only with `force`."""
    return reader.decompress(archive, output, tuple(clips), force=force, jobs=jobs)


def _edited_in_place(archive: str | os.PathLike, output, force: bool) -> None:
    """An edit without `output` replaces `archive`: only when asked to with `force`, as `mcz remove -f`."""
    if output is None and not force:
        raise FileExistsError(errno.EEXIST, "already exists: give output= for a new archive, or force=True to "
                              "replace it in place", os.fspath(archive))


def remove(archive: str | os.PathLike, patterns: str | Iterable[str], output: str | os.PathLike | None = None, *,
           force: bool = False) -> dict:
    """Write `archive` without the clips whose stored path or file name matches one of `patterns`
    (shell-style, as `decompress`'s `clips`), as `mcz remove` does: to `output`, or in place
    with `force`; every other clip is copied as it is and decodes to the same bytes. The old
    archive is intact until the new one is complete. Returns the summary: "removed" (their
    paths), "clips" (left), "output", "output_bytes", "seconds". MocapFormatError if no clip
    matches, or every clip would go."""
    from mocapzip.archive import edit  # the encoder's modules only when editing: open() is faster without

    patterns = [patterns] if isinstance(patterns, str) else list(patterns)
    if not patterns or not all(isinstance(p, str) for p in patterns):
        raise TypeError(f"remove() takes one or more patterns (str), got {patterns!r}")
    _edited_in_place(archive, output, force)
    return edit.remove(archive, patterns, output, force=force)


def append(archive: str | os.PathLike, inputs: str | os.PathLike | Iterable[str | os.PathLike],
           output: str | os.PathLike | None = None, *, under: str | None = None, asf: str | os.PathLike | None = None,
           units: str | None = None, jobs: int | None = None, force: bool = False, progress: bool = True) -> dict:
    """Write `archive` with the AMC and BVH clips under `inputs` (folders or files) added, as
    `mcz append` does: to `output`, or in place with `force`. The new clips are coded with the
    archive's settings (so within its bounds), each in the archive's class nearest it where that
    takes fewer bytes than a class of their own (docs/editing.md); every clip already
    there is copied as it is. `under`: a folder of the archive to store them in ("09": 09_01.amc
    as 09/09_01.amc); `asf`, `units`, `jobs` (every core by default) and `progress` as
    `compress`'s. The old archive is intact until the new one is complete. Returns the summary:
    "added" (their stored paths), "in_stored_classes" (those coded in the archive's classes),
    "clips" (in all), "output", "output_bytes", "seconds".
    MocapFormatError if the archive already holds a clip under one of their paths."""
    from mocapzip.archive import edit

    _edited_in_place(archive, output, force)
    with _bars(progress):
        return edit.append(archive, _input_paths(inputs), output, force=force, jobs=_every_core(jobs), under=under,
                           asf=asf, units=units)
