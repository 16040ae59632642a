"""What every representation returns and promises."""

from __future__ import annotations

from dataclasses import dataclass, field

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


class Representation(Stage):
    """A stage of kind "representation"; its one parameter, `axes_from_positions`, leaves out the
    axes of bones whose rotation follows from joint positions (`positions.solved_bones`)."""

    kind = "representation"
    has_root_track = False  # the aligned family moves root translation and heading to a track of their own

    def __init__(self, axes_from_positions: bool = False):
        self.axes_from_positions = bool(axes_from_positions)

    @property
    def name(self) -> str:
        return self.codec_id

    def params(self) -> dict:
        return {"axes_from_positions": self.axes_from_positions}

    def forward(self, model: SkeletonModel, motion) -> Encoded:
        """A Motion (AMC clip of `model`'s skeleton) -> Encoded."""
        raise NotImplementedError

    def inverse(self, model: SkeletonModel, encoded: Encoded, layout) -> np.ndarray:
        """Encoded -> channel values (F, C) in `layout` (a Motion or ChannelLayout)."""
        raise NotImplementedError
