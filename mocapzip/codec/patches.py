"""Frame patches: the residual layer that holds every joint of every frame within `--max-error`.

A clip's coding bounds its mean error. A few frames keep a joint further off: fast events
(impacts, foot strikes) that the kept band smooths over, and glitches in the source that
the decoder cannot guess. For those frames alone the archive stores a correction of the
decoded AMC channel values, rounded to a multiple of the frame's step: the least change that
puts the frame's joints where the source has them (`ratecontrol.max_error`), or, where that
does not pass, the residual, original minus decoded. The step halves with each refinement
level, so the encoder raises a frame's level until the frame passes, and any frame can reach
its original values exactly.

Steps are in cm of joint movement: a translation channel's is `step_cm` in the file's length
unit, a rotation channel's is `step_cm / LEVER_CM` radians (in the clip's angle unit), the
angle that moves a joint LEVER_CM away by `step_cm`.

Stream `patch/NNNNN` (format 5 on; docs/format.md): `f32 step_cm`, then one "context"
matrices stream (`codec.entropy.coefficients`) of two matrices, P = the row's `patched_frames`:
(P, 2) each patched frame's gap after the one before (the first's: its index) and its level,
and (P, C) the residual ints; a row whose frame directly follows the previous row's, at the
same level, holds its difference from that row (residuals of neighbouring frames are alike).
Each stream's models start fresh: priors trained on every clip's patches saved 0.2-0.4 % of
the archive at CMU -e 1 --max-error 3 to 5, less than they cost.
"""

from __future__ import annotations

import math
import struct
from dataclasses import dataclass

import numpy as np

from mocapzip.codec.basis import unpack
from mocapzip.codec.entropy.coefficients import decode_matrices, encode_matrices
from mocapzip.motion.skeleton import ChannelLayout, SkeletonModel

LEVER_CM = 100.0  # a rotation step of s / LEVER_CM radians moves a joint this far away by s cm
MAX_LEVEL = 40  # steps down to step_cm * 2**-40: far below any printed digit, so every frame can be exact


@dataclass
class FramePatches:
    """Corrections of some frames' decoded channel values: what `patch/NNNNN` stores."""

    step_cm: float  # as stored (float32)
    frames: np.ndarray  # (P,) increasing frame indices within the clip
    levels: np.ndarray  # (P,) refinement levels: the frame's step is step_cm * 2**-level
    ints: np.ndarray  # (P, C) the residuals in steps

    @property
    def matrices(self) -> list[np.ndarray]:
        """As stored: (P, 2) gaps and levels, (P, C) ints, a row after its neighbour at one level as the difference."""
        gaps = np.diff(self.frames, prepend=-1) - 1
        stored = self.ints.copy()
        follows = (gaps[1:] == 0) & (self.levels[1:] == self.levels[:-1])
        stored[1:][follows] -= self.ints[:-1][follows]
        return [np.column_stack([gaps, self.levels]), stored]

    def payload(self) -> bytes:
        return struct.pack("<f", self.step_cm) + encode_matrices(self.matrices)

    @classmethod
    def from_payload(cls, blob: bytes, n_frames: int, width: int, count: int) -> "FramePatches":
        """The patches of a clip of `n_frames` x `width` values, `count` of them (its row's
        `patched_frames`). The blob may come from anyone: shapes, frames and levels are checked."""
        (step_cm,) = unpack("<f", blob, 0)
        if not (math.isfinite(step_cm) and step_cm > 0):
            raise ValueError(f"patch step {step_cm!r} is not a positive number")
        header, stored = decode_matrices(blob[4:], [(count, 2), (count, width)])  # a version-2 stream is refused
        gaps, levels = header[:, 0], header[:, 1]
        if np.any(gaps < 0) or np.any(gaps >= n_frames) or np.any(levels < 0) or np.any(levels > MAX_LEVEL):
            raise ValueError(f"patch gaps must be within 0..{n_frames - 1} and levels within 0..{MAX_LEVEL}")
        frames = np.cumsum(gaps + 1) - 1  # below count x n_frames: no overflow
        if count and frames[-1] >= n_frames:
            raise ValueError(f"patched frame {frames[-1]} is past the clip's {n_frames} frames")
        ints, shadow = stored.copy(), stored.astype(np.float64)  # the float sums catch a run that overflows int64
        follows = (gaps[1:] == 0) & (levels[1:] == levels[:-1])
        for i in np.flatnonzero(follows) + 1:  # in order: a run of rows adds up
            ints[i] += ints[i - 1]
            shadow[i] += shadow[i - 1]
        if np.any(np.abs(shadow) >= 2.0**62):
            raise ValueError("patch values beyond 2**62")
        return cls(step_cm, frames, levels, ints)

    def apply(self, values: np.ndarray, steps: np.ndarray) -> None:
        """Add the corrections to decoded channel `values` (frames x C), in place. `steps`:
        `channel_steps` of the clip, the channels' steps for 1 cm."""
        for frame, level, ints in zip(self.frames, self.levels, self.ints):
            values[frame] += ints * frame_steps(steps, self.step_cm, int(level))


def rotation_channels(model: SkeletonModel, layout: ChannelLayout) -> np.ndarray:
    """(C,) whether each channel of `layout` is a rotation (else a translation)."""
    return np.array([channel.startswith("r") for bone, count in zip(layout.bones, layout.counts)
                     for channel in model.channels[model.index[bone]][:count]], bool)


def channel_steps(model: SkeletonModel, layout: ChannelLayout) -> np.ndarray:
    """(C,) each channel's patch step for a step of 1 cm: 1 cm in the file's length unit for
    translations, 1 / LEVER_CM radians in the clip's angle unit for rotations."""
    to_unit = 180.0 / math.pi if layout.angle_unit == "deg" else 1.0
    return np.where(rotation_channels(model, layout), to_unit / LEVER_CM, 1.0 / model.cm_per_unit)


def frame_steps(steps: np.ndarray, step_cm: float, level: int) -> np.ndarray:
    """(C,) the channel steps of a frame at `level`: `steps` (`channel_steps`) times step_cm * 2**-level."""
    return steps * (step_cm * 2.0 ** -level)
