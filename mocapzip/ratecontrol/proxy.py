"""Cheap stand-ins for the end-to-end error, which the rate control calibrates per clip.

The end-to-end error of a coding (decode, channels, forward kinematics, joint distances) costs
tens of microseconds per frame, and a step search needs it for every step and band it tries.
The proxies here measure the error where it is cheap: in the representation, as the mean
joint error of the weighted pose error (`mean_joint_error`), taken straight from the coefficients'
error through the inverse transform and the basis, with no decode to channels. That is not the
promised error (the decoder's inverse kinematics and the rounding of the written text come
between), but it moves with it: the ratio of the two is nearly constant for a clip, so a
factor measured by one true check carries over to the next step (`ratecontrol.encode.code_clip`).
"""

from __future__ import annotations

import math
from functools import cached_property

import numpy as np
import scipy.fft
from numba import njit

from mocapzip.codec.clip_stream import unscale_root
from mocapzip.codec.quantise import UniformQuantiser
from mocapzip.motion.rotations import axis_rotation

# A band of k rows is decoded at m measured frames by an (m x k) product instead of an inverse
# transform of all n frames while m k <= COST n: about where the two cost the same (numpy's
# BLAS, scipy's DCT); a length whose DCT is slow (large prime factors) moves that point.
SYNTHESIS_COST = 64
SLOW_LENGTH_SYNTHESIS_COST = 512


class TruncationProxy:
    """Mean joint error (cm), in the representation, of keeping the first q components of an
    orthonormal basis (`mean_joint_error`). The root track is kept exactly, as PCA leaves it."""

    def __init__(self, poses: np.ndarray, mean: np.ndarray, components: np.ndarray, columns: slice):
        self._centred = poses - mean
        self._coef = self._centred @ components
        self._mean, self._components, self._columns = mean, components, columns

    def truncated(self, q: int) -> np.ndarray:
        """The poses as the first q components keep them (what the true score decodes)."""
        return self._mean + self._coef[:, :q] @ self._components[:, :q].T

    def __call__(self, q: int) -> float:
        error = self._centred - self._coef[:, :q] @ self._components[:, :q].T
        return mean_joint_error(error, self._columns)


_NO_ROOT = (np.zeros((0, 4)), np.zeros((0, 3, 3)), np.zeros((0, 1, 3)))


def mean_joint_error(error: np.ndarray, columns: slice, root: np.ndarray | None = None,
                     to_character: np.ndarray | None = None, lever: np.ndarray | None = None) -> float:
    """The mean over frames and joints of the size of a weighted pose error (frames x columns).

    A joint's size is the norm of its position columns (`columns`, 3 per joint) plus, with a
    root track, the root's error moved into the character frame, and the weighted bone-axis
    columns after them spread evenly over the joints (an axis error of e moves a joint by about
    e: that is what their weight means). The root's error (frames x 4: translation, heading)
    moves each joint by the translation (`to_character`, frames x 3 x 3, turns it into the
    character frame) plus the heading error times the joint's `lever` (frames x joints x 3),
    and counts as one more joint, the root's own translation. With no position columns
    (channels, which have no root track), one size per frame: the norm of the whole error.
    """
    if root is None:
        root, to_character, lever = _NO_ROOT
    arrays = (np.ascontiguousarray(a, dtype=np.float64) for a in (error, root, to_character, lever))
    error, root, to_character, lever = arrays  # one compiled signature
    return float(_mean_joint_error(error, columns.start, columns.stop, root, to_character, lever))


@njit(cache=True)
def _mean_joint_error(error, start, stop, root, to_character, lever):
    """`mean_joint_error` in one pass (numpy spent 0.3 ms a call on 316 frames in temporaries)."""
    frames, width = error.shape
    joints = (stop - start) // 3
    with_root = root.shape[0] > 0
    shift = np.zeros(3)
    total = 0.0
    for f in range(frames):
        rest = 0.0
        for c in range(stop, width):
            rest += error[f, c] * error[f, c]
        if joints == 0:
            total += math.sqrt(rest)
            continue
        if with_root:
            for k in range(3):
                shift[k] = root[f, 0] * to_character[f, 0, k] + root[f, 1] * to_character[f, 1, k] + \
                    root[f, 2] * to_character[f, 2, k]
            total += math.sqrt(shift[0] * shift[0] + shift[1] * shift[1] + shift[2] * shift[2])
        for j in range(joints):
            size = rest / joints
            for k in range(3):
                v = error[f, start + 3 * j + k]
                if with_root:
                    v += shift[k] + root[f, 3] * lever[f, j, k]
                size += v * v
            total += math.sqrt(size)
    count = frames * max(joints, 1) + (frames if with_root and joints > 0 else 0)
    return total / count if count else math.nan


class CodingProxy:
    """Mean joint error (cm) of a clip coded at a quantiser step and band, measured in the representation.

    `pose_coef`: the temporal coefficients (`transform`) of the clip's basis coefficients (frames x
    Q); `root_coef`: those of its scaled root track (frames x 4) or None; `basis`: the class basis
    (columns x Q); `columns`: its position columns (`Representation.joint_position_columns`); `residual`: the
    pose error the basis leaves before any quantisation (frames x columns); `character`: for
    representations with a root track, the clip's joint positions in the character frame (frames
    x joints x 3, cm) and its heading (frames, radians). `frames`: the frames measured.

    The error is the coefficients' error taken back through the inverse transform and the basis,
    so a band's dropped events and the quantiser's noise land on the joints and frames they hit
    (`mean_joint_error`). The root track's error is added as vectors, linearised (the translation,
    plus the heading error times each joint's lever arm about the vertical): both lose the same
    fast events, and in the world their errors largely cancel. What is left out (inverse
    kinematics, the rounding of the written text) the calibration absorbs.
    """

    def __init__(self, pose_coef: np.ndarray, root_coef: np.ndarray | None, basis: np.ndarray, columns: slice,
                 residual: np.ndarray, transform, dead_zone: float,
                 character: tuple[np.ndarray, np.ndarray] | None = None, frames=slice(None)):
        self.pose_coef, self.root_coef, self.dead_zone = pose_coef, root_coef, dead_zone
        self.transform, self.basis, self.columns, self.frames = transform, basis, columns, frames
        self.n_frames = len(pose_coef)
        self._residual = residual[frames]
        if root_coef is not None:
            local, heading = character
            # a heading error d moves a joint at p (character frame) by d * p @ TURN, where TURN is
            # d/d(angle) of the rotation about +Y at 0 (axis_rotation at 90 degrees, minus its fixed axis)
            turn = axis_rotation("y", np.pi / 2) - np.diag([0.0, 1.0, 0.0])
            self._lever = local[frames] @ turn
            # contiguous once here, not copied by `mean_joint_error` on every call
            self._to_character = np.ascontiguousarray(np.swapaxes(axis_rotation("y", heading[frames]), -1, -2))
        self._coef = pose_coef if root_coef is None else np.hstack([pose_coef, root_coef])
        n_measured = len(range(*frames.indices(self.n_frames)))
        fast = scipy.fft.next_fast_len(self.n_frames, real=True) == self.n_frames
        cost = SYNTHESIS_COST if fast else SLOW_LENGTH_SYNTHESIS_COST
        rows = min(cost * self.n_frames // n_measured, self.n_frames)
        self._synthesised_rows = rows if hasattr(transform, "synthesis") else 0  # bands up to this many rows
        self._synthesis_of: dict[bool, np.ndarray] = {}  # by `edge`: the synthesis functions' first rows so far

    def kept_rows(self, band: float) -> int:
        """Rows a band keeps (as `code_clip` zeroes the rest)."""
        return math.ceil(band * self.n_frames)

    def __call__(self, pose_step: float, root_step: float, band: float = 1.0) -> float:
        kept = self.kept_rows(band)
        curves = self._curve_error(pose_step, root_step, kept)
        error = self._residual + curves[:, : self.pose_coef.shape[1]] @ self.basis.T
        if self.root_coef is None:
            return mean_joint_error(error, self.columns)
        root = unscale_root(curves[:, self.pose_coef.shape[1] :])
        return mean_joint_error(error, self.columns, root, self._to_character, self._lever)

    def _curve_error(self, pose_step: float, root_step: float, kept: int) -> np.ndarray:
        """original - decoded of the pose curves (and the scaled root track's, as more columns) at the
        measured frames. A narrow band keeps few rows: then the decoded curves are the synthesis
        functions of those rows times their values, cheaper than a whole inverse transform."""
        decoded = np.empty((kept, self._coef.shape[1]))
        q = self.pose_coef.shape[1]
        for columns, step in ((slice(0, q), pose_step), (slice(q, None), root_step)):
            quantiser = UniformQuantiser(step, self.dead_zone)
            decoded[:, columns] = quantiser.dequantise(quantiser.quantise(self._coef[:kept, columns]))
        if kept <= self._synthesised_rows:
            curves = self._synthesis(kept) @ decoded
            for columns in self._edge_columns:  # the columns a transform codes by their ends synthesise otherwise
                curves[:, columns] = self._synthesis(kept, edge=True) @ decoded[:, columns]
            return self._original - curves
        error = self._coef.copy()
        error[:kept] -= decoded
        return self._inverse(error)[self.frames]

    @cached_property
    def _original(self) -> np.ndarray:
        """The curves at the measured frames, as the transform gives them back."""
        return self._inverse(self._coef)[self.frames]

    def _inverse(self, coef: np.ndarray) -> np.ndarray:
        """The inverse transform of pose and root coefficients side by side, each matrix on its own, as
        the decoder takes them: a transform's first columns may be coded differently (`EdgeDctTransform`)."""
        q = self.pose_coef.shape[1]
        if not self._edge_columns or coef.shape[1] == q:
            return self.transform.inverse(coef, self.n_frames)
        return np.hstack([self.transform.inverse(coef[:, :q], self.n_frames),
                          self.transform.inverse(coef[:, q:], self.n_frames)])

    @cached_property
    def _edge_columns(self) -> list[slice]:
        """The columns of `_coef` the transform codes by their ends: the first of the pose's and of the root's."""
        if not hasattr(self.transform, "edge_width"):
            return []
        q = self.pose_coef.shape[1]
        widths = [(0, self.transform.edge_width(self.n_frames, q))]
        if self.root_coef is not None:
            widths.append((q, self.transform.edge_width(self.n_frames, self.root_coef.shape[1])))
        return [slice(start, start + width) for start, width in widths if width]

    def _synthesis(self, kept: int, edge: bool = False) -> np.ndarray:
        """(measured frames, kept): the decoded curves of each of the first `kept` unit coefficients
        (`edge`: of the columns coded by their ends)."""
        cached = self._synthesis_of.get(edge)
        if cached is None or cached.shape[1] < kept:
            rows = min(max(kept, 2 * (0 if cached is None else cached.shape[1])), self._synthesised_rows)
            extra = {"edge": True} if edge else {}
            self._synthesis_of[edge] = cached = self.transform.synthesis(self.n_frames, rows, self.frames, **extra)
        return cached[:, :kept]

