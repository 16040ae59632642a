"""A clip as the codec sees it: its skeleton model, its representation, and how to score a decode.

The score is the product's promise: the mean joint-position error in cm after the
decoded representation is turned back into AMC channels (rounded to the 6
significant digits written to disk, for the final check) and run through forward
kinematics, against the original clip's joint positions.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np

from .formats.amc import AmcStyle, Motion, read_amc
from .formats.asf import read_asf
from .formats.errors import MocapFormatError
from .inputs import ClipSource, record_skip
from .kinematics import forward
from .metrics import joint_distances
from .progress import progress
from .representations import get_representation
from .representations.base import Encoded
from .skeleton import ChannelLayout, SkeletonModel


@dataclass
class LoadedClip:
    source: ClipSource
    skeleton_index: int
    model: SkeletonModel
    motion: Motion
    encoded: Encoded | None  # None in lossless mode: the channels are coded as they are
    representation_name: str | None
    positions: np.ndarray | None  # (F, J, 3) cm, original joint positions (lossy mode)
    axis_weight_cm: float = 1.0

    @cached_property
    def weights(self) -> np.ndarray:
        return pose_weights(self.model, self.representation_name, self.encoded.poses.shape[1], self.axis_weight_cm)

    @cached_property
    def poses(self) -> np.ndarray:
        """The representation's poses, weighted (see `pose_weights`): the space the codec works in."""
        return self.encoded.poses * self.weights

    @property
    def root(self) -> np.ndarray | None:
        return self.encoded.root

    @property
    def layout(self) -> ChannelLayout:
        return self.model.layout(self.motion)

    def error(self, poses: np.ndarray, root: np.ndarray | None, frames=slice(None), final: bool = False):
        """(mean, max) joint-position error in cm of decoded `poses`/`root` for the original `frames`.

        `final` rounds the channels as the AMC writer will (the source's number style), as on disk.
        """
        values = channels_from(self.model, self.representation_name, self.layout, poses / self.weights, root,
                               self.encoded.params)
        if final:
            values = round_as_written(values, self.motion.style)
        decoded = forward(self.model, values, self.layout).positions
        distances = joint_distances(self.positions[frames], decoded)
        return float(distances.mean()), float(distances.max())


def round_as_written(values: np.ndarray, style: AmcStyle) -> np.ndarray:
    """What the AMC text of `values` in `style` reads back as (vectorised)."""
    if style.notation == "f":
        return np.round(values, style.digits)
    digits = style.digits
    with np.errstate(divide="ignore"):
        exponent = np.floor(np.log10(np.abs(values)))
    exponent = np.where(np.isfinite(exponent), exponent, 0)
    scale = 10.0 ** (digits - 1 - exponent)
    return np.round(values * scale) / scale


def pose_weights(model: SkeletonModel, representation_name: str, width: int, axis_weight_cm: float) -> np.ndarray:
    """Per-column weights of a pose: joint positions (cm) count 1, bone axis vectors (unit
    vectors) count `axis_weight_cm`, the distance at which an axis error becomes a position
    error. PCA and the uniform quantiser then spend bits where they move joints.
    Channels (angles) are left unweighted.
    """
    weights = np.ones(width)
    if representation_name != "channels":
        n_positions = 3 * model.n_joints if representation_name == "positions" else 3 * (model.n_joints - 1)
        weights[n_positions:] = axis_weight_cm
    return weights


def channels_from(model: SkeletonModel, representation_name: str, layout: ChannelLayout,
                  poses: np.ndarray, root: np.ndarray | None, params: dict) -> np.ndarray:
    """Decoded representation -> AMC channel values in `layout`."""
    representation = get_representation(representation_name)
    return representation.inverse(model, Encoded(poses, root, params), layout)


def skeleton_params(model: SkeletonModel, representation_name: str, layout: ChannelLayout) -> dict:
    """The representation's per-clip parameters; they depend on the skeleton only, so the
    decoder re-derives them (from a one-frame rest pose) instead of storing them."""
    rest = Motion(list(layout.bones), list(layout.counts), np.zeros((1, layout.width)), np.array([1]),
                  [":RADIANS" if layout.angle_unit == "rad" else ":DEGREES"])
    return get_representation(representation_name).forward(model, rest).params


def load_clips(sources: list[ClipSource], skeleton_paths: list, representation_name: str | None,
               axis_weight_cm: float = 1.0, skipped: list | None = None) -> list[LoadedClip]:
    """Read every clip (checking it against its skeleton) and convert it to the representation.

    A clip that cannot be read raises MocapFormatError or OSError; with a `skipped` list it
    is left out and recorded there instead (`inputs.record_skip`).
    """
    skeletons: dict = {}
    clips = []
    for source in progress(sources, desc="read", unit="clip"):
        try:
            if source.asf not in skeletons:
                skeleton = read_asf(source.asf)
                skeletons[source.asf] = (skeleton, SkeletonModel.from_asf(skeleton))
            skeleton, model = skeletons[source.asf]
            motion = read_amc(source.amc, skeleton)  # checks every bone line against the skeleton
        except (MocapFormatError, OSError) as exc:
            if skipped is None:
                raise
            record_skip(skipped, source, exc)
            continue
        encoded = positions = None
        if representation_name is not None:
            encoded = get_representation(representation_name).forward(model, motion)
            positions = forward(model, motion.values, motion).positions
        clips.append(LoadedClip(source, skeleton_paths.index(source.asf), model, motion, encoded,
                                representation_name, positions, axis_weight_cm))
    return clips
