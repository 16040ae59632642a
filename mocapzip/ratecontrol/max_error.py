"""The last stage of a clip's rate control: what it achieved on every joint of every frame, and
`--max-error`, enforced by frame patches (`codec.patches`).

The coding searched before this bounds the clip's mean error. Here its decode is scored per
joint and frame, end to end through the written AMC values, and each frame with a joint
further than the bound gets a patch: its residual in the channels that move those joints,
at the coarsest level (step max_error, halved per level) that brings every joint of the
frame within the bound without raising the frame's summed error (so the clip's mean, already
within `-e`, cannot rise). Frames are independent once decoded to channels, so each is
settled on its own.

Patching only the frames that need it measured cheaper than a finer coding of the whole
clip: the frames over a few cm are short, isolated events (docs/fidelity.md).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from mocapzip.codec.patches import MAX_LEVEL, FramePatches, channel_steps, frame_steps
from mocapzip.codec.quantise import UniformQuantiser
from mocapzip.motion import compiled


PATCH_DEAD_ZONE = 0.45  # small residuals left out: a frame then passes at a finer level with fewer values
# A clip whose patches take more than PATCH_SHARE of its bytes is coded again with its mean aim LOWERED:
# a finer coding leaves fewer frames to patch (it pays at tight bounds, 3 cm and below at -e 1).
PATCH_SHARE = 0.15
LOWERED = 0.75
MAX_LOWERINGS = 4


@dataclass(frozen=True)
class Achieved:
    """A clip's joint-position error in cm, every joint of every frame as written: what its row stores."""

    mean: float
    p99: float
    max: float

    @classmethod
    def of(cls, distances: np.ndarray) -> "Achieved":
        """From (frames, joints) distances; the mean summed as the encoder's checks sum it (pairwise)."""
        flat = np.ascontiguousarray(distances, dtype=np.float64).ravel()
        if not flat.size:
            return cls(0.0, 0.0, 0.0)
        return cls(float(compiled.np_sum(flat) / flat.size), float(np.percentile(flat, 99)), float(flat.max()))


def achieved(clip, check, max_error_cm: float | None = None) -> tuple[Achieved, FramePatches | None]:
    """What a decode of `clip` (`check`: its `inputs.clip.FinalCheck`) achieves, and with `max_error_cm`
    the patches (None if no frame needs one) that hold every joint within it; the errors are
    those with the patches."""
    values, original = check.values, clip.positions
    distances = check.distances.copy()
    if max_error_cm is None:
        return Achieved.of(distances), None
    bad = np.flatnonzero(distances.max(axis=1) > max_error_cm)
    if not bad.size:
        return Achieved.of(distances), None
    steps = channel_steps(clip.model, clip.layout)
    step_cm = float(np.float32(max_error_cm))
    residual = clip.motion.values[bad] - values[bad]
    chains = _chain_channels(clip)
    before = distances[bad]
    # the channels a frame corrects: those of the joints beyond the bound, and their ancestors'
    corrected = (before > max_error_cm).astype(np.int64) @ chains > 0
    levels = np.zeros(len(bad), np.int64)
    ints = np.zeros(residual.shape, np.int64)
    pending = np.arange(len(bad))
    while pending.size:
        if levels[pending].max() > MAX_LEVEL:
            frame = int(bad[pending[np.argmax(levels[pending])]])
            raise ValueError(f"frame {frame} stays beyond {max_error_cm:g} cm at every patch level")
        row_steps = np.array([frame_steps(steps, step_cm, int(level)) for level in levels[pending]])
        kept = np.where(corrected[pending], residual[pending], 0.0)
        ints[pending] = UniformQuantiser(1.0, PATCH_DEAD_ZONE).quantise(kept / row_steps)
        patched = values[bad[pending]] + ints[pending] * row_steps  # as FramePatches.apply adds them
        after = clip.decode_tail.joint_distances(clip.as_written(patched), original[bad[pending]])
        passed = (after.max(axis=1) <= max_error_cm) & (after.sum(axis=1) <= before[pending].sum(axis=1))
        distances[bad[pending[passed]]] = after[passed]
        failed, after = pending[~passed], after[~passed]
        # a joint beyond the bound, or worse than before, adds its chain; with nothing to add, a finer level
        worse = (after > max_error_cm) | (after > before[failed])
        wider = corrected[failed] | (worse.astype(np.int64) @ chains > 0)
        finer = np.all(wider == corrected[failed], axis=1)
        corrected[failed] = wider
        levels[failed[finer]] += 1
        pending = failed
    return Achieved.of(distances), FramePatches(step_cm, bad, levels, ints)


def _chain_channels(clip) -> np.ndarray:
    """(joints, channels) 0/1: the layout's channels that move each joint (its own and its ancestors')."""
    tail, parents = clip.decode_tail, clip.model.parents
    chains = np.zeros((len(parents), tail.width), np.int64)
    for j in range(len(parents)):  # parents come before children
        if parents[j] >= 0:
            chains[j] = chains[parents[j]]
        if tail.first_column[j] >= 0:
            chains[j, tail.first_column[j]:tail.first_column[j] + tail.n_channels[j]] = 1
    return chains


def smallest_within(coded_at: Callable, target: float, max_error_cm: float | None):
    """The smallest of `coded_at(aim)` (a coding with `.size` and `.patch_bytes`) over mean aims target,
    LOWERED x target, ...: lowered while patches take more than PATCH_SHARE of a coding's bytes and
    the codings shrink."""
    best = coded_at(target)
    for _ in range(MAX_LOWERINGS if max_error_cm is not None else 0):
        if best.patch_bytes <= PATCH_SHARE * best.size:
            break
        target *= LOWERED
        candidate = coded_at(target)
        if candidate.size >= best.size:
            break
        best = candidate
    return best
