"""What every representation returns and promises, its decode included."""

from __future__ import annotations

from abc import ABC, abstractmethod
from dataclasses import dataclass, field
from typing import ClassVar

import numpy as np

from mocapzip.motion.skeleton import SkeletonModel
from mocapzip.stages import Stage

ROOT_TRACK_WIDTH = 4  # a root track's values per frame: x, y, z (cm) and yaw (rad)


@dataclass
class Encoded:
    """One clip in a representation: what the codec compresses.

    `poses` is the (frames x M) matrix, one pose per row. `root` is the separate
    root-motion track (frames x ROOT_TRACK_WIDTH: x, y, z in cm and yaw in radians, unwrapped)
    for the aligned family, None otherwise. `params` holds the few per-clip
    values the inverse needs (e.g. the height scale), small enough to store as is, and
    `params["twist"]`, a `positions.TwistChoice` for solved bones (absent: the default).
    """

    poses: np.ndarray
    root: np.ndarray | None = None
    params: dict[str, float | np.ndarray] = field(default_factory=dict)


class PoseDecoder(ABC):
    """One representation's decode for one skeleton and channel layout, as `Representation.decoder`
    builds it: the codec's weighted poses and root track -> channel values, what the
    representation's `inverse` gives (tests/test_compiled_decode.py holds the two together).
    The encoder's error check runs it many times a clip, so the marker representations' is
    compiled (`positions.MarkerDecoder`)."""

    # the 2-dof solved bones whose solution the decode chooses, in the row order of `flips`
    twisted: np.ndarray = np.zeros(0, np.int64)

    @abstractmethod
    def channels(self, weighted_poses: np.ndarray, root: np.ndarray | None, reference: np.ndarray | None = None,
                 flips: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
        """(channel values (F, C), flips (len(twisted), F)). Twists turn towards `reference` (the
        encoder, which knows the original: `MarkerDecoder.twist_reference`) or follow `flips` (the
        decoder: `flip_flags`); with neither, the default solution."""

    def check_directions(self, weighted_poses: np.ndarray) -> None:
        """ValueError if a direction the decode normalises is no direction (`positions.MarkerDecoder`);
        a representation that normalises none has nothing to check."""

    def flip_flags(self, flips: dict[int, np.ndarray], n_frames: int) -> np.ndarray:
        """`positions.TwistChoice.flips` as `channels` takes them: (len(twisted), frames) bool."""
        flags = np.zeros((len(self.twisted), n_frames), np.bool_)
        for r, j in enumerate(self.twisted):
            if j in flips:
                flags[r] = flips[j]
        return flags


class Representation(Stage, ABC):
    """A stage of kind "representation"; its one parameter, `axes_from_positions`, leaves out the
    axes of bones whose rotation follows from joint positions (`positions.solved_bones`).

    Each representation owns its decode: its column weights, where its joint positions sit, its
    root track's width and the decoder the decode tail runs (`weighted.DecodeTail`). A class
    that leaves one out cannot be registered (`stages.register` refuses abstract classes), and
    one that brings its own `inverse` must bring its own `decoder`, so that it is never decoded
    as the class it extends is.
    """

    kind = "representation"
    root_width: ClassVar[int] = 0  # values per frame of its root track (ROOT_TRACK_WIDTH for the aligned family)

    def __init_subclass__(cls, **kwargs):
        super().__init_subclass__(**kwargs)
        if "inverse" in vars(cls) and "decoder" not in vars(cls):
            raise TypeError(f"representation {cls.__name__} defines its own inverse but not its decoder: "
                            f"the decode tail would decode it as {cls.__mro__[1].__name__} does")

    def __init__(self, axes_from_positions: bool = False):
        self.axes_from_positions = bool(axes_from_positions)

    @property
    def name(self) -> str:
        return self.codec_id

    def params(self) -> dict:
        return {"axes_from_positions": self.axes_from_positions}

    @abstractmethod
    def forward(self, model: SkeletonModel, motion) -> Encoded:
        """A Motion (AMC clip of `model`'s skeleton) -> Encoded."""

    @abstractmethod
    def inverse(self, model: SkeletonModel, encoded: Encoded, layout) -> np.ndarray:
        """Encoded -> channel values (F, C) in `layout` (a Motion or ChannelLayout)."""

    @abstractmethod
    def joint_position_columns(self, model: SkeletonModel) -> slice:
        """The pose columns that hold joint positions (cm), which the rate control's proxies
        take as moving joints by their own error; empty if none do."""

    @abstractmethod
    def column_weights(self, model: SkeletonModel, layout, axis_weight_cm: float) -> np.ndarray:
        """(M,) weights of a pose's columns in `layout`: the codec works on poses times these
        (`inputs.clip.LoadedClip.poses`), so PCA and the uniform quantiser spend bits where
        they move joints. `axis_weight_cm`: the distance at which a unit axis vector's error
        becomes a position error."""

    @abstractmethod
    def decoder(self, tables, params: dict, axis_weight_cm: float) -> PoseDecoder:
        """This representation's decode for the skeleton and layout of `tables`
        (`weighted.ChannelTables`), with the clip's `params` (`Encoded.params`)."""
