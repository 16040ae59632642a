"""The last stage of a clip's rate control: what it achieved on every joint of every frame, and
`--max-error`, enforced by frame patches (`codec.patches`).

The coding searched before this bounds the clip's mean error. Here its decode is scored per
joint and frame, end to end through the written AMC values, and each frame with a joint
further than the bound gets a patch: a correction of the channels that move those joints,
the least that puts the frame's joints back (`_least_corrections`), at the coarsest level (step
COARSEST x max_error, halved per level) that brings every joint of the frame within the bound
without raising the frame's summed error (so the clip's mean, already within `-e`, cannot
rise; with --repair-glitches the glitch's joints are left out of both, and `smallest_within`
codes the clip finer should its mean rise). Frames are independent once decoded to channels,
so each is settled on its own.

Patching only the frames that need it measured cheaper than a finer coding of the whole
clip: the frames over a few cm come in short runs (at -e 1, a median 5 frames beyond 3 cm;
docs/fidelity.md). The least change rather than the source's values: on the shared CMU set at
-e 1 --max-error 3 the residuals spent most of their bits on a hand's twist, an Euler triple's
other branch and whole turns (sources store angles up to 990 degrees), none of which moves a
joint; with it (and COARSEST) patches took 4.1 rather than 16.2 bytes per patched frame, and
the archive was 32 % smaller.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from mocapzip.codec.patches import MAX_LEVEL, FramePatches, channel_steps, frame_steps, rotation_channels
from mocapzip.codec.quantise import UniformQuantiser
from mocapzip.formats.errors import MocapFormatError
from mocapzip.formats.text import MAX_ABS_VALUE, in_value_range
from mocapzip.inputs.glitches import glitch_mask, repaired_ranges
from mocapzip.motion import compiled
from mocapzip.motion.contacts import contacts
from mocapzip.ratecontrol.target import Bounds


# A patch's coarsest step is COARSEST x its bound: a least change often passes at a step that
# leaves only a few channels nonzero. 4 made CMU subjects 01, 07, 09 and 135 at -e 1 --max-error 3
# 8 % smaller than 1 (2: 6 %, 8: as 4).
COARSEST = 4
PATCH_DEAD_ZONE = 0.45  # small residuals left out: a frame then passes at a finer level with fewer values
# A clip whose patches take more than PATCH_SHARE of its bytes is coded again with its mean aim LOWERED:
# a finer coding leaves fewer frames to patch (it pays at tight bounds, 3 cm and below at -e 1).
PATCH_SHARE = 0.3  # 0.15 before patches took the least change: as small at 3 cm, and fewer codings tried
LOWERED = 0.75
MAX_LOWERINGS = 4


class TargetError(MocapFormatError):
    """No coding of a clip meets its error target or bound: they are below the input's own precision."""


@dataclass(frozen=True)
class Achieved:
    """A clip's error in cm, every joint of every frame as written: what its row stores."""

    mean: float
    p99: float
    max: float
    repaired: tuple = ()  # with --repair-glitches: [first, last, cm] per repaired run (`glitches.repaired_ranges`)
    vertex: float | None = None  # the worst shell vertex (ACL's metric, `Bounds.shell_cm`) of any bone in any frame

    @classmethod
    def of(cls, distances: np.ndarray, repaired: tuple = (), vertex: float | None = None) -> "Achieved":
        """From (frames, joints) distances; the mean summed as the encoder's checks sum it (pairwise)."""
        flat = np.ascontiguousarray(distances, dtype=np.float64).ravel()
        if not flat.size:
            return cls(0.0, 0.0, 0.0, repaired, vertex)
        return cls(float(compiled.np_sum(flat) / flat.size), float(np.percentile(flat, 99)), float(flat.max()), repaired,
                   vertex)


def achieved(clip, check, bounds: Bounds = Bounds()) -> tuple[Achieved, FramePatches | None]:
    """What a decode of `clip` (`check`: its `inputs.clip.FinalCheck`) achieves, and the patches
    (None if no frame needs one) that hold its joints within `bounds` (`joint_limits`) and its
    shell vertices within `bounds.vertex_error_cm`; the errors are those with the patches.

    A frame beyond a vertex bound corrects the channels that turn the vertex's bone and move its
    origin (theirs and their ancestors'), as a joint beyond its bound corrects its chain."""
    values, original = check.values, clip.positions
    distances = check.distances.copy()
    repaired = None
    if bounds.repair_glitches and bounds.on_joints:  # with no bound nothing is let past one
        repaired = glitch_mask(clip.model, clip.glitches, clip.motion.frame_numbers)
    limits = joint_limits(clip, bounds, repaired)
    tail, source = clip.decode_tail, clip.motion.values
    vertices = tail.shell_distances(clip.as_written(values.copy()), source, bounds.shell_cm)
    vertex_limit = np.inf if bounds.vertex_error_cm is None else bounds.vertex_error_cm
    bones = tail.shell_bones
    vertex_held = np.ones(vertices.shape, bool)  # repaired joints' bones (--repair-glitches) are not held
    if repaired is not None:
        vertex_held = ~(repaired[:, bones.origin_at] | repaired[:, bones.rotation_of])
    over = np.zeros(len(distances), bool) if limits is None else np.any(distances > limits, axis=1)
    bad = np.flatnonzero(over | np.any((vertices > vertex_limit) & vertex_held, axis=1))
    if not bad.size:
        _check_range(clip, values)
        return _with_repairs(distances, repaired, clip, vertices), None
    if limits is None:
        limits = np.full(distances.shape, np.inf)
    steps = channel_steps(clip.model, clip.layout)
    step_cm = float(np.float32(COARSEST * next(b for b in (bounds.max_error_cm, bounds.contact_error_cm,
                                                         bounds.vertex_error_cm) if b is not None)))
    residual = _turns_removed(source[bad] - values[bad], clip)
    chains = _chain_channels(clip)
    bone_chains = chains[bones.rotation_of] | chains[bones.origin_at]  # (B, channels)
    before, limit = distances[bad], limits[bad]
    vertex_before, vertex_held = vertices[bad], vertex_held[bad]
    # repaired joints (--repair-glitches) neither call for corrections nor count against one
    held = np.ones(before.shape, bool) if repaired is None else ~repaired[bad]
    # the channels a frame corrects: those of the joints and bones beyond their bound, and their ancestors'
    vertex_over = (vertex_before > vertex_limit) & vertex_held
    corrected = ((before > limit).astype(np.int64) @ chains + vertex_over.astype(np.int64) @ bone_chains) > 0
    # a frame starts at the level whose step is COARSEST times its tightest broken bound
    tightest = np.minimum(np.where(before > limit, limit, np.inf).min(axis=1),
                          np.where(vertex_over.any(axis=1), vertex_limit, np.inf))
    levels = np.maximum(0, np.ceil(np.log2(step_cm / tightest / COARSEST) - 1e-6)).astype(np.int64)
    ints = np.zeros(residual.shape, np.int64)
    pending = np.arange(len(bad))
    exact, first_levels = residual, levels.copy()
    least = np.zeros(len(bad), bool)  # the frames corrected by their least change, not to the source's values
    if bounds.vertex_error_cm is None:  # vertices see the twist that a joint's least correction leaves
        residual, least = _least_corrections(tail, values[bad], original[bad], corrected, held, steps, exact, limit,
                                             before)
    while pending.size:
        stuck = pending[(levels[pending] > MAX_LEVEL) & least[pending]]
        if stuck.size:  # written with the file's digits, a least change may never pass: the source's values do
            residual[stuck], least[stuck], levels[stuck] = exact[stuck], False, first_levels[stuck]
        if levels[pending].max() > MAX_LEVEL:
            frame = int(bad[pending[np.argmax(levels[pending])]])
            raise _unbounded(clip, f"frame {frame} stays beyond its bound at every patch level")
        row_steps = np.array([frame_steps(steps, step_cm, int(level)) for level in levels[pending]])
        kept = np.where(corrected[pending], residual[pending], 0.0)
        try:
            ints[pending] = UniformQuantiser(1.0, PATCH_DEAD_ZONE).quantise(kept / row_steps)
        except ValueError:  # a value so large that its patch would pass the quantiser's range
            raise _unbounded(clip, f"frame {int(bad[pending[0]])} needs a patch larger than patches hold") from None
        patched = clip.as_written(values[bad[pending]] + ints[pending] * row_steps)  # as FramePatches.apply adds them
        after = tail.joint_distances(patched, original[bad[pending]])
        vertex_beyond = np.zeros((len(pending), len(bones.names)), bool)  # scored only against a bound
        if bounds.vertex_error_cm is not None:
            vertex_after = tail.shell_distances(patched, source[bad[pending]], bounds.shell_cm)
            vertex_beyond = (vertex_after > vertex_limit) & vertex_held[pending]
        passed = np.all(after <= limit[pending], axis=1) & ~vertex_beyond.any(axis=1) & (
            (after * held[pending]).sum(axis=1) <= (before[pending] * held[pending]).sum(axis=1))
        distances[bad[pending[passed]]] = after[passed]
        failed, after, vertex_beyond = pending[~passed], after[~passed], vertex_beyond[~passed]
        # a joint beyond its bound or worse than before, or a bone beyond its bound, adds its chain;
        # with nothing to add, a finer level
        worse = ((after > limit[failed]) | (after > before[failed])) & held[failed]
        wider = corrected[failed] | ((worse.astype(np.int64) @ chains + vertex_beyond.astype(np.int64) @ bone_chains) > 0)
        finer = np.all(wider == corrected[failed], axis=1)
        corrected[failed] = wider
        grown = failed[~finer & least[failed]]
        if grown.size:  # more channels free: a new least change
            residual[grown], least[grown] = _least_corrections(tail, values[bad[grown]], original[bad[grown]],
                                                               corrected[grown], held[grown], steps, exact[grown],
                                                               limit[grown], before[grown])
        levels[failed[finer]] += 1
        pending = failed
    patches = FramePatches(step_cm, bad, levels, ints)
    patched = values.copy()
    patches.apply(patched, steps)
    _check_range(clip, patched)
    # the patched frames' vertices, scored once on what is written
    vertices[bad] = tail.shell_distances(clip.as_written(patched[bad]), source[bad], bounds.shell_cm)
    return _with_repairs(distances, repaired, clip, vertices), patches


def _turns_removed(residual: np.ndarray, clip) -> np.ndarray:
    """`residual` less the whole turns in its rotation channels: an angle and that angle plus 360
    degrees turn a bone alike, and sources store angles up to 990 degrees (cmu/01/01_09)."""
    turn = 360.0 if clip.layout.angle_unit == "deg" else 2 * np.pi
    rotations = rotation_channels(clip.model, clip.layout)
    residual[:, rotations] -= turn * np.round(residual[:, rotations] / turn)
    return residual


def _least_corrections(tail, values, original, free, held, steps, exact, limit, before, iterations: int = 3):
    """(P, C) corrections of the frames' channel `values`, in their `free` channels only, that move
    their `held` joints onto `original` with the least change, counted in patch steps (`steps`):
    damped Gauss-Newton on forward kinematics. A joint's position leaves a bone's twist about
    itself and an Euler triple's other branch free; the source's values (`exact`) spend patch
    bits on both. A frame whose correction does not bring every joint within `limit` without
    raising its summed error keeps `exact`, which can always reach the source; the second array
    says which frames have their least change."""
    count = len(values)
    delta = np.zeros_like(values)
    weight = np.repeat(held.astype(np.float64), 3, axis=1)  # (P, 3J)
    probe = 1e-3  # of a step: far below where forward kinematics bends, far above float rounding
    masks, group = np.unique(free, axis=0, return_inverse=True)  # frames with the same free channels: one batch
    batches = [(np.flatnonzero(group.ravel() == g), np.flatnonzero(mask)) for g, mask in enumerate(masks) if mask.any()]
    for _ in range(iterations):
        current = values + delta
        at = tail.positions(current).reshape(count, -1)
        residual = (original.reshape(count, -1) - at) * weight
        for rows, cols in batches:  # a channel not free in a frame needs no forward kinematics nor a column
            moved = tail.probed_positions(current[rows], cols, probe * steps[cols]).reshape(len(rows), len(cols), -1)
            jacobian = (moved - at[rows, None, :]) / probe * weight[rows, None, :]  # (rows, cols, 3J): per step
            # damped: a channel no joint sees (a twist, another Euler branch) stays where it was
            normal = jacobian @ jacobian.transpose(0, 2, 1) + 1e-2 * np.eye(len(cols))
            change = np.linalg.solve(normal, jacobian @ residual[rows, :, None])[:, :, 0]
            delta[np.ix_(rows, cols)] += change * steps[cols]
    after = tail.joint_distances(values + delta, original)
    good = np.all(after <= limit, axis=1) & ((after * held).sum(axis=1) <= (before * held).sum(axis=1))
    return np.where(good[:, None], delta, exact), good


def _check_range(clip, values: np.ndarray) -> None:
    """TargetError where a decoded value would pass +-MAX_ABS_VALUE: the decoder refuses such an
    archive (`Archive._check_range`), so a source value at the limit cannot be coded lossy."""
    if not in_value_range(values):
        raise TargetError(f"its decoded values would pass +-{MAX_ABS_VALUE:g}, the most any file may hold (values "
                          "that close to the limit cannot be coded lossy); use --lossless", clip.source.motion)


def _unbounded(clip, why: str) -> TargetError:
    """A clip whose written numbers are too coarse (or too large) for its bound: one line naming it.
    Its values print with the digits its file used (`as_written`): near 1e8, 6 digits are metres."""
    return TargetError(f"no coding holds its joints within the bound ({why}): the bound is finer than the "
                       "precision of the clip's numbers allows; use a larger --max-error, or --lossless",
                       clip.source.motion)


def joint_limits(clip, bounds: Bounds, repaired: np.ndarray | None = None) -> np.ndarray | None:
    """(frames, joints) the bound on each joint's error, cm: max_error_cm (inf without), the tighter
    contact_error_cm on the source's planted foot joints, and none on the `repaired` joints;
    None without a bound on single joints."""
    if not bounds.on_joints:
        return None
    limits = np.full(clip.positions.shape[:2], np.inf if bounds.max_error_cm is None else bounds.max_error_cm)
    if bounds.contact_error_cm is not None:
        planted = contacts(clip.model, clip.positions, clip.fps)  # the clip's own rate: contacts are speeds
        limits[planted] = np.minimum(limits[planted], bounds.contact_error_cm)
    if repaired is not None:
        limits[repaired] = np.inf
    return limits


def _with_repairs(distances: np.ndarray, repaired: np.ndarray | None, clip, vertices: np.ndarray) -> Achieved:
    ranges = () if repaired is None else tuple(repaired_ranges(repaired, distances, clip.motion.frame_numbers))
    return Achieved.of(distances, ranges, float(vertices.max()) if vertices.size else 0.0)


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


def smallest_within(coded_at: Callable, target: float, bounded: bool):
    """The smallest of `coded_at(aim)` (a coding with `.size`, `.patch_bytes` and `.achieved`) over
    mean aims target, LOWERED x target, ...: lowered while patches take more than PATCH_SHARE of
    a coding's bytes and the codings shrink, or while the mean is over `target` (patches keep
    the held joints' summed error; a repaired glitch's joints may move either way)."""
    best, aim = coded_at(target), target
    for _ in range(MAX_LOWERINGS if bounded else 0):
        over = best.achieved.mean > target
        if not over and best.patch_bytes <= PATCH_SHARE * best.size:
            break
        aim *= LOWERED
        candidate = coded_at(aim)
        if not over and (candidate.size >= best.size or candidate.achieved.mean > target):
            break
        best = candidate
    return best
