"""Physics-based motion features (Krüger et al. 2007, seed 002, section 3.1): the whole body's
centre-of-mass acceleration and the angular momenta of the hands and feet, per frame.

They compare motions of one class where joint positions or angles would not: they stay
meaningful when averaged down to a few Hz (`timewarp.multiscale_dtw` aligns with them), and
they do not see where a subject walks or which way it faces.

Segment masses and centres of mass are Dempster's, as tabulated by D. A. Winter, *Biomechanics
and Motor Control of Human Movement* (Table 4.1): a share of the body's mass per segment, and
the segment's centre as a share of its length from the proximal joint. A skeleton's bones are
matched to segments by name (`SEGMENTS`: the ASF names of CMU and HDM05 and the usual BVH ones).
Two simplifications: the head and neck's 8.1 % sits halfway along the bones named head or neck
(split by length), and the trunk's 49.7 % halfway between the root and the shoulders (the
upper arms' proximal ends), Winter's trochanter-to-shoulder segment. Heights are +y.
"""

from __future__ import annotations

import re
from dataclasses import dataclass

import numpy as np

from mocapzip.formats.errors import MocapFormatError
from mocapzip.motion.skeleton import SIDE_SUFFIX, SkeletonModel, side_of

# segment: (bone name pattern, share of body mass per bone, centre as a share of the length from
# the proximal joint). Names are matched lower-case, less a side suffix (Bandai's UpperArm_L); the
# first pattern a name matches wins, so forearm comes before arm.
SEGMENTS = {
    "forearm": (r"(radius|forearm|lowerarm)$", 0.016, 0.430),
    "hand": (r"hand$", 0.006, 0.506),
    "upper arm": (r"(humerus|shldr|upperarm|^(l|r|left|right)_?arm)$", 0.028, 0.436),
    "foot": (r"foot$", 0.0145, 0.50),
    "shank": (r"(tibia|shin|lowerleg|calf|^(l|r|left|right)_?leg)$", 0.0465, 0.433),
    "thigh": (r"(femur|thigh|upleg|upperleg)$", 0.100, 0.433),
    "head and neck": (r"(head|neck)$", 0.081, 0.5),  # 0.081 for all such bones together
}
TRUNK_MASS = 0.497  # halfway between the root and the shoulders
MOMENTUM_SEGMENTS = ("hand", "foot")  # the segments whose angular momenta are features (two of each)


@dataclass(frozen=True)
class BodySegments:
    """Which bones of a skeleton carry mass, found once per skeleton (`body_segments`)."""

    bones: np.ndarray  # (S,) model joint of each massive bone (its segment runs from the parent's point to its own)
    masses: np.ndarray  # (S,) share of body mass
    centres: np.ndarray  # (S,) centre as a share of the bone's length from its proximal end
    shoulders: np.ndarray  # (2,) the upper arms' bones: the trunk reaches their proximal ends
    momentum: np.ndarray  # (4,) where the hands and the feet are in `bones`: their angular momenta are features


def body_segments(model: SkeletonModel) -> BodySegments:
    """Match the skeleton's bones to Winter's segments (MocapFormatError if hands, feet or upper arms are missing)."""
    kinds: dict[str, list[int]] = {kind: [] for kind in SEGMENTS}
    for j, name in enumerate(model.names):
        if model.parents[j] < 0 or ">" in name:  # the root; a BVH model's link bones ("P>child") have no mass
            continue
        for kind, (pattern, _, _) in SEGMENTS.items():
            if re.search(pattern, SIDE_SUFFIX.sub("", name.lower())):
                kinds[kind].append(j)
                break
    for kind in ("upper arm", *MOMENTUM_SEGMENTS):
        if len(kinds[kind]) != 2:
            found = ", ".join(model.names[j] for j in kinds[kind]) or "none"
            raise MocapFormatError(f"physics features need a left and a right {kind}; bones named like one: {found}")
    bones, masses, centres = [], [], []
    lengths = np.linalg.norm(model.offsets, axis=1)
    for kind, (_, mass, centre) in SEGMENTS.items():
        if kind == "head and neck" and kinds[kind]:
            share = lengths[kinds[kind]] / max(lengths[kinds[kind]].sum(), 1e-12)
        else:
            share = np.ones(len(kinds[kind]))
        bones += kinds[kind]
        masses += list(mass * share)
        centres += [centre] * len(kinds[kind])
    momentum = [bones.index(j) for kind in MOMENTUM_SEGMENTS for j in _left_first(model, kinds[kind])]
    return BodySegments(np.array(bones), np.array(masses), np.array(centres), np.array(kinds["upper arm"]),
                        np.array(momentum))


def _left_first(model: SkeletonModel, pair: list[int]) -> list[int]:
    """A left and a right bone, the left first (lhand, Hand_L, LeftHand; CMU's BVH lists the right first)."""
    left = [j for j in pair if side_of(model.names[j]) == "l"]
    if len(left) != 1:
        raise MocapFormatError(f"cannot tell left from right among {', '.join(model.names[j] for j in pair)}")
    return left + [j for j in pair if j != left[0]]


def physics_features(model: SkeletonModel, positions: np.ndarray, rotations: np.ndarray, fps: float,
                     segments: BodySegments | None = None) -> np.ndarray:
    """(frames, 5, 3): the centre-of-mass acceleration (cm/s^2), then the angular momenta of the left
    and right hands and the left and right feet about their proximal joints (share of body mass x cm^2/s), each in the
    body's heading frame: turned about +y by the root's heading, so that a walk goes the same
    whichever way it faces. `positions` and `rotations` are `kinematics.forward`'s (cm)."""
    segments = segments or body_segments(model)
    proximal = positions[:, model.parents[segments.bones]]
    centres = proximal + segments.centres[None, :, None] * (positions[:, segments.bones] - proximal)
    shoulders = positions[:, model.parents[segments.shoulders]].mean(axis=1)
    trunk = 0.5 * (positions[:, 0] + shoulders)
    mass = segments.masses.sum() + TRUNK_MASS
    com = (np.einsum("s,fsc->fc", segments.masses, centres) + TRUNK_MASS * trunk) / mass
    acceleration = _derivative(_derivative(com, fps), fps)
    # angular momentum of a segment about the joint it turns around: r x m v, r from that joint to the
    # segment's centre, m v the centre's linear momentum (a foot's is large in its swing, 0 in its stance)
    momentum = segments.momentum
    arm = centres[:, momentum] - proximal[:, momentum]
    momenta = segments.masses[momentum][None, :, None] * np.cross(arm, _derivative(centres[:, momentum], fps))
    features = np.concatenate([acceleration[:, None], momenta], axis=1)
    return _in_heading_frame(features, rotations[:, 0])


def _derivative(x: np.ndarray, fps: float) -> np.ndarray:
    """d/dt along frames (central differences, one-sided at the ends; zeros for a single frame)."""
    if len(x) < 2:
        return np.zeros_like(x)
    return np.gradient(x, 1.0 / fps, axis=0)


def _in_heading_frame(vectors: np.ndarray, root_rotations: np.ndarray) -> np.ndarray:
    """(frames, K, 3) vectors turned about +y by minus the root's heading: the angle of the root's
    x axis (the first row of its rotation, row convention) across the floor."""
    heading = np.arctan2(root_rotations[:, 0, 2], root_rotations[:, 0, 0])
    cos, sin = np.cos(heading)[:, None], np.sin(heading)[:, None]
    x, y, z = vectors[..., 0], vectors[..., 1], vectors[..., 2]
    return np.stack([cos * x + sin * z, y, -sin * x + cos * z], axis=-1)
