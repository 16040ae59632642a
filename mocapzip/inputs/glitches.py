"""Glitches in the source: motion that is broken as captured, reported and never silently fixed.

The codec's bounds hold against the source as written (`--max-error`), glitch included; this
module finds and names them, for `mcz inspect --check` and the summary `compress` prints,
and with `--repair-glitches` says which joints are let past the bounds (`glitch_mask`). Four kinds, per bone and run of frames (thresholds from the shared CMU set, and why:
docs/fidelity.md, "Glitches in the source"):

- `jump`: a joint moves faster than JUMP_CM_PER_S between two frames, its parent not (the
  whole limb below a flipped joint jumps with it; the joint where it starts is named);
- `limits`: a rotation channel beyond its ASF `limits` by more than LIMIT_MARGIN_DEG, with the
  value taken at whichever turn (+-360 degrees) is nearest the range;
- `frozen`: every channel of a bone bit for bit the same for FROZEN_FRAMES frames or more,
  where the bone moves elsewhere in the clip (a marker lost and its last value held);
- `zeroed`: every channel of a bone exactly 0 for ZEROED_FRAMES frames or more, where it is
  not 0 elsewhere in the clip.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass

import numpy as np

from mocapzip.formats.amc import Motion
from mocapzip.formats.asf import Skeleton
from mocapzip.motion.skeleton import SkeletonModel

JUMP_CM_PER_S = 2500.0  # 25 m/s: 20.8 cm per frame at 120 Hz, the 99.999th percentile of CMU joint moves
LIMIT_MARGIN_DEG = 90.0  # CMU's limits are loose guides that normal motion passes by up to 60 degrees
FROZEN_FRAMES = 30  # a quarter second at 120 Hz: held, not merely slow
ZEROED_FRAMES = 2


@dataclass(frozen=True)
class Glitch:
    kind: str  # jump | limits | frozen | zeroed
    bone: str
    first: int  # AMC frame numbers, inclusive
    last: int
    detail: str

    def as_dict(self) -> dict:
        return asdict(self)

    def __str__(self) -> str:
        frames = f"frame {self.first}" if self.first == self.last else f"frames {self.first}-{self.last}"
        return f"{frames}: {self.bone}: {self.kind}: {self.detail}"


def find_glitches(skeleton: Skeleton | None, model: SkeletonModel, motion: Motion, positions: np.ndarray,
                  fps: float) -> list[Glitch]:
    """Every glitch of a clip, in frame order; `positions`: its joints (frames x joints x 3, cm);
    `skeleton`: its ASF, whose limits it checks (None: a BVH clip, which states no limits)."""
    numbers = motion.frame_numbers
    found = _jumps(model, positions, fps, numbers) + _held(model, motion, numbers)
    if skeleton is not None:
        found += beyond_limits(skeleton, model, motion)
    return sorted(found, key=lambda g: (g.first, g.bone, g.kind))


def _runs(flags: np.ndarray) -> list[tuple[int, int]]:
    """(start, end) index pairs, end exclusive, of the runs of True in a 1-D bool array."""
    edges = np.flatnonzero(np.diff(np.concatenate([[False], flags, [False]]).astype(np.int8)))
    return list(zip(edges[::2].tolist(), edges[1::2].tolist()))


def _jumps(model: SkeletonModel, positions: np.ndarray, fps: float, numbers: np.ndarray) -> list[Glitch]:
    if len(positions) < 2:
        return []
    speed = np.linalg.norm(np.diff(positions, axis=0), axis=2) * fps  # (frames - 1, joints) cm/s
    fast = speed > JUMP_CM_PER_S
    parents = model.parents
    starts = fast & ~np.where(parents >= 0, fast[:, np.maximum(parents, 0)], False)
    found = []
    for j in np.flatnonzero(starts.any(axis=0)):
        for a, b in _runs(starts[:, j]):
            found.append(Glitch("jump", model.point_name(j), int(numbers[a]), int(numbers[b]),
                                f"moves {speed[a:b, j].max() / fps:.1f} cm in one frame "
                                f"({speed[a:b, j].max() / 100:.0f} m/s)"))
    return found


def _held(model: SkeletonModel, motion: Motion, numbers: np.ndarray) -> list[Glitch]:
    found = []
    for bone, columns in model.layout(motion).columns().items():
        values = motion.values[:, columns]
        if values.shape[1] == 0 or len(values) < 2:
            continue
        zero = np.all(values == 0, axis=1)
        if not zero.all():
            for a, b in _runs(zero):
                if b - a >= ZEROED_FRAMES:
                    found.append(Glitch("zeroed", bone, int(numbers[a]), int(numbers[b - 1]),
                                        f"all {values.shape[1]} values 0 for {b - a} frames"))
        same = np.concatenate([[False], np.all(values[1:] == values[:-1], axis=1)])  # frame f equals f - 1
        if same[1:].all():
            continue  # constant all along: a bone the capture never moved, not a held marker
        for a, b in _runs(same):
            held = b - a + 1  # the run's frames and the one before it
            if held >= FROZEN_FRAMES and not zero[a]:
                found.append(Glitch("frozen", bone, int(numbers[a - 1]), int(numbers[b - 1]),
                                    f"values held for {held} frames"))
    return found


def beyond_limits(skeleton: Skeleton, model: SkeletonModel, motion: Motion,
                  margin_deg: float = LIMIT_MARGIN_DEG) -> list[Glitch]:
    """The `limits` glitches: runs of a rotation channel beyond its ASF limits by more than `margin_deg`."""
    numbers, columns = motion.frame_numbers, model.layout(motion).columns()
    full_turn, margin = (360.0, margin_deg) if skeleton.angle_unit == "deg" else (2 * np.pi, np.radians(margin_deg))
    found = []
    for bone in skeleton.bones:
        if bone.name not in columns or not bone.limits:
            continue
        values = motion.values[:, columns[bone.name]]
        for k, (dof, (low, high)) in enumerate(zip(bone.dof, bone.limits)):
            if not dof.startswith("r") or k >= values.shape[1] or not (np.isfinite(low) and np.isfinite(high)):
                continue
            v = values[:, k]
            middle = (low + high) / 2
            nearest = v - full_turn * np.round((v - middle) / full_turn)  # the turn of v nearest the range
            excess = np.maximum(nearest - high, low - nearest)
            for a, b in _runs(excess > margin):
                worst = a + int(np.argmax(excess[a:b]))
                found.append(Glitch("limits", bone.name, int(numbers[a]), int(numbers[b - 1]),
                                    f"{dof} {v[worst]:g} outside its limits [{low:g}, {high:g}]"))
    return found


REPAIRABLE = ("jump", "limits")  # spikes the decoder's smooth curves pass over; a frozen or zeroed run
# is a held pose, which the codec follows: there is nothing to smooth it towards


def glitch_mask(model: SkeletonModel, glitches: list[Glitch], frame_numbers: np.ndarray) -> np.ndarray:
    """(frames, joints) bool: the joints each REPAIRABLE glitch throws off, its bone's and every joint
    below it, over its frames; what `--repair-glitches` leaves to the decoder instead of patching."""
    mask = np.zeros((len(frame_numbers), len(model.names)), bool)
    at = {model.point_name(j): j for j in range(len(model.names))}  # a jump names its point: a BVH's End Site
    for glitch in (g for g in glitches if g.kind in REPAIRABLE):
        frames = (frame_numbers >= glitch.first) & (frame_numbers <= glitch.last)
        mask[np.ix_(frames, [at[glitch.bone]])] = True
    for j in range(1, len(model.parents)):  # parents come before children
        mask[:, j] |= mask[:, model.parents[j]]
    return mask


def repaired_ranges(mask: np.ndarray, distances: np.ndarray, frame_numbers: np.ndarray) -> list[list]:
    """[first, last, cm] per run of frames with a repaired joint (`glitch_mask`): its AMC frame
    numbers and the largest distance of any joint in it from the source, rounded up to 0.001 cm."""
    out = []
    for a, b in _runs(mask.any(axis=1)):
        out.append([int(frame_numbers[a]), int(frame_numbers[b - 1]), math.ceil(float(distances[a:b].max()) * 1000) / 1000])
    return out
