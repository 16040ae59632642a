"""Foot contacts, and foot skate: where a foot is planted, and how much it slides once decoded.

A foot joint (a joint named like a toe or a foot: CMU and HDM05's `ltoes`, `lfoot`, ...) is
planted in a frame when it is low, within CONTACT_HEIGHT_CM of its own lowest level in the
clip (the 1st percentile of its height: a ball joint stands higher than a toe tip, and the
two sides of a skeleton differ by a few cm), and nearly still, moving slower than
CONTACT_SPEED_CM_S across the floor. Heights are along +y, the ASF/AMC up axis. Thresholds
from the shared CMU set (docs/fidelity.md, "Planted feet").
"""

from __future__ import annotations

import re

import numpy as np

from mocapzip.motion.skeleton import SkeletonModel, side_of

FOOT_NAME = re.compile(r"toe|foot", re.IGNORECASE)
CONTACT_HEIGHT_CM = 5.0
CONTACT_SPEED_CM_S = 20.0


def foot_joints(model: SkeletonModel) -> np.ndarray:
    """Indices of the joints named like a toe or a foot."""
    return np.array([j for j, name in enumerate(model.names) if FOOT_NAME.search(name)], np.int64)


def horizontal_speed(positions: np.ndarray, fps: float) -> np.ndarray:
    """(frames, joints) cm/s across the floor (x, z), each frame's speed from the frame before
    (the first frame's from the one after)."""
    if len(positions) < 2:
        return np.zeros(positions.shape[:2])
    step = np.linalg.norm(np.diff(positions[:, :, [0, 2]], axis=0), axis=2) * fps
    return np.concatenate([step[:1], step])


def contacts(model: SkeletonModel, positions: np.ndarray, fps: float) -> np.ndarray:
    """(frames, joints) bool: the foot joints planted in each frame (the source's positions, cm)."""
    planted = np.zeros(positions.shape[:2], bool)
    feet = foot_joints(model)
    if not feet.size or not len(positions):
        return planted
    height = positions[:, feet, 1]
    planted[:, feet] = (height - np.percentile(height, 1, axis=0) < CONTACT_HEIGHT_CM) & (horizontal_speed(positions[:, feet], fps)
                                                                < CONTACT_SPEED_CM_S)
    return planted


STEP_FRAMES = 10  # foot_strikes: contact runs, and the gaps between them, shorter than this are smoothed over


def foot_strikes(model: SkeletonModel, positions: np.ndarray, fps: float) -> dict[str, list[int]]:
    """{"l": frames, "r": frames} where each foot comes down: the starts of its contact runs (any of
    its foot joints planted; a joint's side from its name, `side_of`), after gaps and
    runs under STEP_FRAMES are smoothed over. A run from the first frame is no strike."""
    planted = contacts(model, positions, fps)
    found = {}
    for side in ("l", "r"):
        joints = [j for j in foot_joints(model) if side_of(model.names[j]) == side]
        edges = np.flatnonzero(np.diff(np.concatenate([[0], planted[:, joints].any(axis=1), [0]]).astype(int)))
        runs: list[list[int]] = []
        for first, end in zip(edges[::2], edges[1::2]):
            if runs and first - runs[-1][1] < STEP_FRAMES:
                runs[-1][1] = end
            else:
                runs.append([first, end])
        found[side] = [int(first) for first, end in runs if end - first >= STEP_FRAMES and first > 0]
    return found


def foot_skate(original: np.ndarray, decoded: np.ndarray, planted: np.ndarray, fps: float) -> float:
    """Mean over the planted foot joints and frames of the decoded clip's speed across the floor
    minus the source's (cm/s): how much more a planted foot slides once decoded (0 with none)."""
    if not planted.any():
        return 0.0
    return float((horizontal_speed(decoded, fps) - horizontal_speed(original, fps))[planted].mean())
