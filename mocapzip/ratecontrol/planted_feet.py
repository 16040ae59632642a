"""Which stances a clip's foot lock holds (`compress --plant-feet`; the lock: `codec.foot_lock`).

A stance is a run of the source's planted frames of one foot joint (`motion.contacts`), with
gaps of up to MERGE_GAP frames closed (the speed test flickers at its threshold) and runs
shorter than MIN_FRAMES dropped. A stance is held only where the source itself stands still:
within MAX_SPREAD_CM of its mean position (a foot rolling from heel to toe is planted by the
contact test but moves). What they give: `mcz bench DIR --plant-feet` (docs/fidelity.md).

The lock must not cost the clip its bounds. A stance whose lock raises the summed joint error
of the frames it touches is dropped; if the clip's mean is then still over `-e`, the clip keeps
no lock. `--max-error` and `--contact-error` are enforced after the lock, by frame patches.
"""

from __future__ import annotations

import numpy as np

from mocapzip.codec.foot_lock import Stances, hold, legs
from mocapzip.inputs.clip import FinalCheck
from mocapzip.motion.contacts import contacts, foot_joints

MERGE_GAP = 4  # frames
MIN_FRAMES = 8
MAX_SPREAD_CM = 2.0


def candidate_stances(clip) -> Stances:
    """The stances of `clip`'s source (its model, positions and frame rate), of the foot joints
    that have a leg to turn (`foot_lock.legs`)."""
    planted = contacts(clip.model, clip.positions, clip.fps)
    held = {int(j) for leg in legs(clip.model, clip.decode_tail) for j in leg.feet}
    runs = []
    for f, joint in enumerate(foot_joints(clip.model)):
        if joint not in held:
            continue
        for first, end in _runs(planted[:, joint]):
            where = clip.positions[first:end, joint]
            if end - first >= MIN_FRAMES and np.linalg.norm(where - where.mean(axis=0), axis=1).max() <= MAX_SPREAD_CM:
                runs.append((f, first, end - first))
    return Stances.of(runs)


def _runs(mask: np.ndarray) -> list[tuple[int, int]]:
    """[first, end) of each run of True, runs closer than MERGE_GAP + 1 frames joined."""
    edges = np.diff(np.r_[0, mask.astype(np.int8), 0])
    runs: list[list[int]] = []
    for first, end in zip(np.flatnonzero(edges == 1), np.flatnonzero(edges == -1)):
        if runs and first - runs[-1][1] <= MERGE_GAP:
            runs[-1][1] = int(end)
        else:
            runs.append([int(first), int(end)])
    return [(a, b) for a, b in runs]


def planted(clip, check: FinalCheck, error_cm: float) -> tuple[FinalCheck, Stances | None]:
    """`check` with the stances that keep `clip` within `error_cm` held (`codec.foot_lock.hold`),
    and those stances; `check` itself and None where no stance may be held."""
    stances = candidate_stances(clip)
    if not len(stances):
        return check, None
    locked = _locked(clip, check, stances)
    raised = _raised(check.distances, locked.distances, stances)
    if raised.any():  # held again without them: stances of one leg share its frames
        stances = stances.subset(~raised)
        if not len(stances):
            return check, None
        locked = _locked(clip, check, stances)
    if not locked.error[0] <= error_cm:  # over, or not a number
        return check, None
    return locked, stances


def _locked(clip, check: FinalCheck, stances: Stances) -> FinalCheck:
    values = check.values.copy()
    hold(values, stances, clip.model, clip.decode_tail)
    return clip.scored(values, check.twists)


def _raised(before: np.ndarray, after: np.ndarray, stances: Stances) -> np.ndarray:
    """(S,) bool: the stances whose frames, ramps included, sum more joint error locked than not."""
    change = np.cumsum(np.r_[0.0, (after - before).sum(axis=1)])
    lo, hi = stances.windows(len(before))
    return change[hi] - change[lo] > 0
