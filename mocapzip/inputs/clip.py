"""A clip as the codec sees it: its skeleton model, its representation, and how to score a decode.

The score is the product's promise: the mean joint-position error in cm after the
decoded representation is turned back into AMC channels (rounded to the 6
significant digits written to disk, for the final check) and run through forward
kinematics, against the original clip's joint positions.
"""

from __future__ import annotations

import warnings
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from functools import cached_property

import numpy as np

from mocapzip.defaults import DEFAULT_FPS
from mocapzip.formats.amc import Motion
from mocapzip.inputs.discover import ClipSource
from mocapzip.inputs.glitches import Glitch, find_glitches
from mocapzip.inputs.registry import SourceMotion, SourceSkeleton
from mocapzip.motion import compiled
from mocapzip.progress import progress
from mocapzip.representations import get_representation
from mocapzip.representations.base import Encoded
from mocapzip.representations.weighted import DecodeTail
from mocapzip.representations.positions import TwistChoice, flip_ranges, twisted_bones
from mocapzip.motion.skeleton import ChannelLayout, SkeletonModel


@dataclass
class FinalCheck:
    """A decode scored on every frame as written (`LoadedClip.final_check`): what the encoder
    keeps of it, so that measuring its errors per joint and patching it need no second decode."""

    values: np.ndarray  # (F, C) the channels the decoder makes, before the writer rounds them
    distances: np.ndarray  # (F, J) cm, each joint as written against the original
    twists: dict  # twist flips for the clip's row

    @cached_property
    def error(self) -> tuple[float, float]:
        """(mean, max) of `distances`, the mean summed pairwise (as `compiled.fk_distances`)."""
        flat = self.distances.ravel()
        return float(compiled.np_sum(flat) / flat.size), float(flat.max())


@dataclass
class LoadedClip:
    source: ClipSource
    model: SkeletonModel
    motion: Motion
    encoded: Encoded | None  # None in lossless mode: the channels are coded as they are
    representation_name: str | None
    positions: np.ndarray | None  # (F, J, 3) cm, original joint positions (lossy mode)
    axis_weight_cm: float = 1.0
    axes_from_positions: bool = False  # the representation's flag (representations.get_representation)
    glitches: list[Glitch] | None = None  # the source's (`inputs.glitches`; lossy, read with a frame rate)
    fps: float = DEFAULT_FPS  # frames per second (`clip_frame_rate`)
    angle_unit: str = "deg"  # of its rotation channels, as its row in meta says (`SourceMotion.angle_unit`)
    row_extras: dict = field(default_factory=dict)  # what its row keeps beside its values (`registry.Extras`)
    extra_root: np.ndarray | None = None  # channels kept exactly (a lossy BVH clip's extra root: `registry.Extras`)
    _scored_frames: tuple = field(default=(None, None), repr=False, compare=False)  # see _originals

    @property
    def representation(self):
        return get_representation(self.representation_name, self.axes_from_positions)

    @cached_property
    def weights(self) -> np.ndarray:
        return self.representation.column_weights(self.model, self.layout, self.axis_weight_cm)

    @cached_property
    def poses(self) -> np.ndarray:
        """The representation's poses, weighted (`Representation.column_weights`): the space the codec works in."""
        return self.encoded.poses * self.weights

    @property
    def own_poses(self) -> np.ndarray:
        """The clip's weighted poses as its joints are: `poses`, unless the codec codes what a
        prediction misses (`ratecontrol.tensor.PredictedClip`)."""
        return self.poses

    @property
    def root(self) -> np.ndarray | None:
        return self.encoded.root

    @property
    def nbytes(self) -> int:
        """Memory held by the clip's arrays, its weighted poses and its scoring's twist reference
        (`_originals`) counted whether computed yet or not."""
        arrays = [self.motion.values, self.positions]
        reference = 0
        if self.encoded is not None:
            arrays += [self.encoded.poses, self.encoded.poses, self.encoded.root]
            if self.axes_from_positions:
                reference = self.motion.n_frames * len(twisted_bones(self.model)) * 9 * 8
        return sum(a.nbytes for a in arrays if a is not None) + reference

    @property
    def layout(self) -> ChannelLayout:
        return self.model.layout(self.motion)

    def error(self, poses: np.ndarray, root: np.ndarray | None, frames=slice(None)):
        """(mean, max) joint-position error in cm of decoded `poses`/`root` for the original `frames`,
        the channels unrounded (the searches' score; `final_check` scores them as written).
        Solved bones take the twist nearer the original (`final_check` tells the decoder which).
        """
        values, _ = self._decode(poses, root, frames)
        return self.decode_tail.error(values, self._originals(frames)[0])

    def final_check(self, poses: np.ndarray, root: np.ndarray | None) -> FinalCheck:
        """`poses`/`root` decoded and scored on every frame as on disk (`FinalCheck`), with what the
        archive row stores so that decoding them gives the channels scored: the frames where a
        2-dof solved bone takes its other solution (`twist_flips`: `positions.TwistChoice`,
        `flip_ranges`; empty without solved bones). One decode for all of it."""
        values, twist = self._decode(poses, root, slice(None))
        return self.scored(values, {} if twist is None else flip_ranges(twist.flips, self.model))

    def scored(self, values: np.ndarray, twists: dict) -> FinalCheck:
        """Decoded channel `values` (every frame) scored as written: the `FinalCheck` of a decode
        that the encoder changed after `final_check` (the foot lock)."""
        return FinalCheck(values, self.decode_tail.joint_distances(self.as_written(values.copy()),
                                                                   self._originals(slice(None))[0]), twists)

    def as_written(self, values: np.ndarray) -> np.ndarray:
        """`values` rounded, in place, to what the AMC text the writer makes of them reads back as."""
        compiled.round_as_written(values, self.motion.style.notation == "f", self.motion.style.digits)
        return values

    @cached_property
    def decode_tail(self) -> DecodeTail:
        return DecodeTail(self.model, self.representation, self.layout, self.encoded.params, self.axis_weight_cm)

    def _decode(self, poses: np.ndarray, root: np.ndarray | None, frames):
        """(channel values, the TwistChoice made) of decoded weighted `poses` for the original
        `frames`, twists chosen towards the original's (None without solved bones)."""
        original, reference = self._originals(frames)
        if len(poses) != len(original):
            raise ValueError(f"{len(poses)} poses for {len(original)} frames")
        values, flips = self.decode_tail.decoder.channels(poses, root, reference=reference)
        if not self.axes_from_positions:
            return values, None
        return values, TwistChoice({int(j): flips[r] for r, j in enumerate(self.decode_tail.decoder.twisted)})

    def _originals(self, frames) -> tuple[np.ndarray, np.ndarray | None]:
        """The original joint positions of `frames` and the twist reference (`MarkerDecoder.twist_reference`),
        kept for the last slice asked for: the encoder scores the same sample over and over."""
        key = frames.indices(self.motion.n_frames) if isinstance(frames, slice) else None
        if key is not None and self._scored_frames[0] == key:
            return self._scored_frames[1]
        original = np.ascontiguousarray(self.positions[frames])
        reference = None
        if self.axes_from_positions and len(self.decode_tail.decoder.twisted):
            reference = self.decode_tail.decoder.twist_reference(self.motion.values[frames])
        if key is not None:
            self._scored_frames = (key, (original, reference))
        return original, reference


def load_clips(sources: list[ClipSource], representation_name: str | None,
               axis_weight_cm: float = 1.0, axes_from_positions: bool = False, units: str | None = None) -> list[LoadedClip]:
    """Read every clip (checking it against its skeleton) and convert it to the representation;
    `units`: of BVH lengths, where they cannot be inferred. A clip that cannot be read raises
    MocapFormatError or OSError.
    """
    reader = ClipReader(representation_name, axis_weight_cm, axes_from_positions=axes_from_positions, units=units)
    return [reader.read(source) for source in progress(sources, desc="read", unit="clip")]


def clip_frame_rate(stated: float | None, fps: float, from_files: bool = True) -> float:
    """A clip's frame rate: the one its files state (an AMC header or its ASF's documentation,
    a BVH `Frame Time`), else `fps`; always `fps` if not `from_files` (`--fps` given)."""
    return stated if stated and from_files else fps


@dataclass(frozen=True)
class ClipReading:
    """How an archive's clips are read and what their rows say of it: the part of its settings
    (`archive.settings.Settings.clip_reading`) the first pass takes, and its `ClipReader` reads with."""

    representation: str | None  # a registered representation's id; None: lossless, the values as written
    axis_weight_cm: float  # weight of bone axis vectors against positions (`Representation.column_weights`)
    axes_from_positions: bool  # bones whose rotation follows from joint positions store no axis
    fps: float  # clips' frame rate where their files state none; a row names its own only where it differs
    fps_from_files: bool  # a rate the clip's files state wins over `fps`
    repair_glitches: bool  # the glitches found are smoothed over by the coding, not held (the first pass says so)

    @property
    def lossless(self) -> bool:
        return self.representation is None

    def reader(self, budget_bytes: int | None, units: str | None) -> ClipReader:
        """The reader of these clips, keeping them while they fit in `budget_bytes` (None: no limit)."""
        return ClipReader(self.representation, self.axis_weight_cm, budget_bytes, self.axes_from_positions, self.fps,
                          self.fps_from_files, units)


class ClipReader:
    """Reads clips for a codec that visits each several times, keeping those that fit a byte budget.

    A database larger than memory cannot be held at once, and parsing AMC text again costs
    time, so clips handed to `keep` stay in memory while their arrays fit in `budget_bytes`
    (None: no limit) and `load` re-reads only the others. A kept clip leaves when the codec
    is done with it (`forget`). There is no eviction: the codec scans a class's clips
    several times in the same order, and least-recently-used eviction would drop each clip
    just before its next use. Forked workers see the clips kept before the fork.
    """

    def __init__(self, representation_name: str | None, axis_weight_cm: float = 1.0,
                 budget_bytes: int | None = None, axes_from_positions: bool = False, fps: float | None = None,
                 fps_from_files: bool = True, units: str | None = None):
        self.representation_name, self.axis_weight_cm = representation_name, axis_weight_cm
        self.axes_from_positions = axes_from_positions
        self.budget_bytes, self.fps = budget_bytes, fps  # fps None: no frame rate, glitches are not looked for
        self.fps_from_files = fps_from_files
        self.units = units  # of BVH OFFSETs (a UNITS_CM name); None: inferred (`infer_units`)
        self._skeletons: dict = {}  # skeleton path -> SourceSkeleton: small, read once
        self._by_key: dict = {}  # a skeleton file, or (format, text) of a skeleton in a clip file -> SourceSkeleton
        self._glitches: dict[ClipSource, list[Glitch]] = {}  # found once per clip, however often it is read
        self._kept: dict[ClipSource, LoadedClip] = {}
        self._kept_bytes = 0
        self._keeps_loads = False  # a copy in a Dask worker keeps what it reads (`__setstate__`)

    def __getstate__(self) -> dict:
        """Pickled without the clips it keeps: a Dask worker reads them again (`mocapzip.cluster`)."""
        return {**self.__dict__, "_kept": {}, "_kept_bytes": 0}

    def __setstate__(self, state: dict) -> None:
        """A copy in a Dask worker keeps the clips it reads, within the budget: the worker codes a whole
        class, and visits each of its clips several times (`archive.passes.class_coding._class_task`)."""
        self.__dict__.update(state, _keeps_loads=True)

    def read(self, source: ClipSource) -> LoadedClip:
        """Parse the clip (checking every bone line against its skeleton) and convert it; raises
        MocapFormatError or OSError if it cannot be read.

        Without a representation (lossless) a truncated last frame is refused: it could not
        come back byte for byte. Lossy reading drops it (`Motion.dropped_frames`)."""
        lossless = self.representation_name is None
        read = self.motion(source, lossless)
        model, motion = read.model, read.motion
        extras = source.format.extras(read, source, lossless)
        encoded = None
        if self.representation_name is not None:
            encoded = get_representation(self.representation_name, self.axes_from_positions).forward(model, motion)
        clip = LoadedClip(source, model, motion, encoded, self.representation_name, None, self.axis_weight_cm,
                          self.axes_from_positions, angle_unit=read.angle_unit, row_extras=extras.row,
                          extra_root=extras.extra_root)
        if self.fps is not None:
            clip.fps = clip_frame_rate(read.stated_fps, self.fps, self.fps_from_files)
        if encoded is not None:  # the joints the error is measured against, by the check's own kinematics
            clip.positions = clip.decode_tail.positions(motion.values)
            clip.glitches = self._glitches.get(source)
            if clip.glitches is None and self.fps is not None:
                clip.glitches = find_glitches(read.limits, model, motion, clip.positions, clip.fps)
        return clip

    def motion(self, source: ClipSource, lossless: bool = False) -> SourceMotion:
        """The clip as its format reads it (`registry.InputFormat.read`: an AMC's truncated last
        frame refused if `lossless`, else dropped; a BVH file's channels all if `lossless`, else as
        its model takes them); raises MocapFormatError or OSError if it cannot be read."""
        skeleton = self.skeleton(source)
        if skeleton.model is None and not lossless:  # its joints need the model it could not have
            raise skeleton.unmodelled
        return source.format.read(source, skeleton, lossless)

    def skeleton(self, source: ClipSource) -> SourceSkeleton:
        """The skeleton of `source` (its ASF, its BVH file's hierarchy), read once; raises
        MocapFormatError or OSError if it cannot be read. Clips whose own files hold their
        skeleton share one where its text is the same (BVH files of one hierarchy); a skeleton
        file of its own (an ASF) is one skeleton."""
        path = source.skeleton
        if path not in self._skeletons:
            fmt = source.format
            text = fmt.skeleton_text(path)
            key = path if fmt.skeleton_suffix is not None else (fmt.name, text)
            if key not in self._by_key:
                self._by_key[key] = fmt.read_skeleton(text, path, self.units, self.representation_name is None)
            self._skeletons[path] = self._by_key[key]
        return self._skeletons[path]

    def load(self, source: ClipSource) -> LoadedClip:
        """The kept clip, or the clip read again, quietly: its first reading gave its warnings."""
        clip = self._kept.get(source)
        if clip is not None:
            return clip
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            clip = self.read(source)
        if self._keeps_loads:
            self.keep(clip)
        return clip

    def keep(self, clip: LoadedClip) -> None:
        """Hold `clip` for later `load`s if it fits in the budget; its glitches in any case."""
        if clip.glitches is not None:
            self._glitches[clip.source] = clip.glitches
        if self.budget_bytes is None or self._kept_bytes + clip.nbytes <= self.budget_bytes:
            self._kept[clip.source] = clip
            self._kept_bytes += clip.nbytes

    def forget(self, sources) -> None:
        """Free the kept clips among `sources` (the codec is done with them)."""
        for source in sources:
            clip = self._kept.pop(source, None)
            if clip is not None:
                self._kept_bytes -= clip.nbytes


class ClipsOnDemand(Sequence):
    """A list of clips the codec can index, also in forked workers, whose clips are loaded
    (`load(item)`, e.g. through a `ClipReader`) when indexed instead of held all at once. With
    a module-level `load` it pickles as its items alone (`parallel.kept_workers`)."""

    def __init__(self, items: list, load: Callable[[object], LoadedClip]):
        self.items, self.load = items, load

    def __len__(self) -> int:
        return len(self.items)

    def __getitem__(self, index: int) -> LoadedClip:
        return self.load(self.items[index])
