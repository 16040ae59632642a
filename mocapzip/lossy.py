"""The lossy codec: one PCA basis per class, a temporal transform of the projected curves,
uniform dead-zone quantisation and zstd, with the error budget found by search.

Why one quantiser step for every coefficient of a clip: the PCA basis and the DCT are
orthonormal, so a coefficient error of size e costs the same squared pose error
wherever it sits; equal steps are the rate-distortion optimum (equal slopes). The
root track is scaled into the same units (cm) first, yaw by a typical joint radius,
because a yaw error moves a joint by (distance from root) x (angle).
"""

from __future__ import annotations

import io
import struct
from dataclasses import dataclass

import numpy as np

from .codec.entropy import decode_ints, encode_ints, encode_sparse
from .codec.pca import CovarianceAccumulator, PcaBasis
from .codec.quantise import UniformQuantiser
from .search import largest_step, smallest_count

YAW_RADIUS_CM = 50.0  # a typical joint's distance from the root: yaw error x this = cm
MEAN_STEP_CM = 1e-3  # the class mean is kept finely: its error repeats on every frame


@dataclass
class ClassBasis:
    """A class's mean pose and its first Q principal directions, as stored (quantised)."""

    mean: np.ndarray  # (M,)
    components: np.ndarray  # (M, Q)
    bits: int

    @classmethod
    def fit(cls, accumulator: CovarianceAccumulator, q: int, bits: int) -> "ClassBasis":
        pca = PcaBasis.fit(accumulator)
        return cls.quantised(pca.mean, pca.components[:, :q], bits)

    @classmethod
    def quantised(cls, mean: np.ndarray, components: np.ndarray, bits: int) -> "ClassBasis":
        """Round mean and components to what the archive stores, so encoding sees the decoder's basis."""
        basis = cls(mean, components, bits)
        return cls.decode(basis.encode())

    def encode(self) -> bytes:
        limit = 2 ** (self.bits - 1) - 1
        scales = np.maximum(np.abs(self.components).max(axis=0), 1e-12) / limit if self.components.size else np.zeros(0)
        ints = np.round(self.components / np.where(scales == 0, 1, scales)).astype(np.int64)
        out = io.BytesIO()
        out.write(struct.pack("<III", self.mean.size, self.components.shape[1], self.bits))
        out.write(scales.astype("<f4").tobytes())
        for blob in (encode_ints(np.round(self.mean / MEAN_STEP_CM).astype(np.int64)), encode_ints(ints)):
            out.write(struct.pack("<I", len(blob)))
            out.write(blob)
        return out.getvalue()

    @classmethod
    def decode(cls, blob: bytes) -> "ClassBasis":
        m, q, bits = struct.unpack_from("<III", blob, 0)
        pos = 12
        scales = np.frombuffer(blob, "<f4", q, pos).astype(np.float64)
        pos += 4 * q
        parts = []
        for _ in range(2):
            (n,) = struct.unpack_from("<I", blob, pos)
            parts.append(decode_ints(blob[pos + 4 : pos + 4 + n]))
            pos += 4 + n
        mean = parts[0].astype(np.float64) * MEAN_STEP_CM
        components = parts[1].reshape(m, q).astype(np.float64) * scales
        return cls(mean, components, bits)

    @property
    def q(self) -> int:
        return self.components.shape[1]

    def project(self, poses: np.ndarray) -> np.ndarray:
        """Least-squares coefficients (the stored basis is only nearly orthonormal)."""
        if self.q == 0:
            return np.zeros((poses.shape[0], 0))
        coef, *_ = np.linalg.lstsq(self.components, (poses - self.mean).T, rcond=None)
        return coef.T

    def reconstruct(self, coefficients: np.ndarray) -> np.ndarray:
        return self.mean + coefficients @ self.components.T


def scale_root(root: np.ndarray) -> np.ndarray:
    """Root track (x, y, z cm, yaw rad) in cm-equivalent units."""
    return root * np.array([1.0, 1.0, 1.0, YAW_RADIUS_CM])


def unscale_root(scaled: np.ndarray) -> np.ndarray:
    return scaled / np.array([1.0, 1.0, 1.0, YAW_RADIUS_CM])


def dequantise_curves(ints: np.ndarray, step: float, transform, dead_zone: float, n_frames: int) -> np.ndarray:
    return transform.inverse(UniformQuantiser(step, dead_zone).dequantise(ints), n_frames)


@dataclass
class CodedClip:
    """A clip's quantised coefficients: what the archive stores for it."""

    pose_step: float
    pose_ints: np.ndarray  # (frames, Q) transform coefficients
    root_step: float
    root_ints: np.ndarray | None  # (frames, 4), or None for representations without a root track

    def payload(self) -> bytes:
        parts = [encode_sparse(self.pose_ints)]
        if self.root_ints is not None:
            parts.append(encode_sparse(self.root_ints))
        head = struct.pack("<ddB", self.pose_step, self.root_step, len(parts))
        return head + b"".join(struct.pack("<I", len(p)) + p for p in parts)

    @classmethod
    def from_payload(cls, blob: bytes) -> "CodedClip":
        pose_step, root_step, n = struct.unpack_from("<ddB", blob, 0)
        pos = 17
        arrays = []
        for _ in range(n):
            (size,) = struct.unpack_from("<I", blob, pos)
            arrays.append(decode_ints(blob[pos + 4 : pos + 4 + size]))
            pos += 4 + size
        if pos != len(blob):
            raise ValueError("clip payload has trailing bytes")
        return cls(pose_step, arrays[0], root_step, arrays[1] if n > 1 else None)


SEARCH_STRIDE = 4  # the search scores every 4th frame (30 Hz at 120 Hz); the final check scores all
PCA_SHARES = (0.3, 0.5, 0.7)  # candidate shares of the budget for PCA; the rest goes to quantisation


def encode_class(clips, transform, settings):
    """Fit the class basis and code each clip within settings.error_cm; return (basis, coded, errors).

    The budget split is a search: for each candidate PCA share, the class keeps the fewest
    components that bring every clip's PCA-only error under that share, then each clip gets
    the largest quantiser step that keeps its end-to-end error under the whole budget. The
    split with the fewest bytes wins. `settings.split` forces one split instead.
    """
    accumulator = CovarianceAccumulator(clips[0].poses.shape[1])
    for clip in clips:
        accumulator.add(clip.poses)
    pca = PcaBasis.fit(accumulator)
    target = settings.error_cm
    shares = [settings.split[1] / sum(settings.split)] if settings.split else PCA_SHARES
    best = None
    for share in shares:
        q = max(_components_needed(clip, pca, share * target) for clip in clips)
        basis = ClassBasis.quantised(pca.mean, pca.components[:, :q], settings.basis_bits)
        coded, errors = zip(*(_code_clip(clip, basis, transform, settings) for clip in clips))
        size = len(basis.encode()) + sum(len(c.payload()) for c in coded)
        if best is None or size < best[0]:
            best = (size, basis, list(coded), list(errors))
    return best[1], best[2], best[3]


def _components_needed(clip, pca: PcaBasis, target: float) -> int:
    frames = slice(None, None, SEARCH_STRIDE)
    poses = clip.poses[frames]
    centred = poses - pca.mean
    coef = centred @ pca.components

    def error(q: int) -> float:
        approx = pca.mean + coef[:, :q] @ pca.components[:, :q].T
        return clip.error(approx, None if clip.root is None else clip.root[frames], frames)[0]

    return smallest_count(error, target, 0, pca.components.shape[1])


def _code_clip(clip, basis: ClassBasis, transform, settings):
    """The largest quantiser steps that keep this clip within budget, verified on every frame."""
    target, dz = settings.error_cm, settings.dead_zone
    n = clip.motion.n_frames
    pose_coef = transform.forward(basis.project(clip.poses))
    root_coef = None if clip.root is None else transform.forward(scale_root(clip.root))
    sample = slice(None, None, SEARCH_STRIDE)

    def code(pose_step: float, root_step: float) -> CodedClip:
        return CodedClip(pose_step, UniformQuantiser(pose_step, dz).quantise(pose_coef), root_step,
                         None if root_coef is None else UniformQuantiser(root_step, dz).quantise(root_coef))

    def error(poses, root, frames=sample):
        return clip.error(poses[frames], None if root is None else root[frames], frames)[0]

    def decoded(step: float, part: int):
        return reconstruct(code(step, step), basis, transform, dz, n)[part]

    if settings.split and root_coef is not None:
        r_share = settings.split[0] / sum(settings.split)
        root_step, _ = largest_step(lambda s: error(clip.poses, decoded(s, 1)), r_share * target, 1e-4, 1e3)
        pose_step, _ = largest_step(lambda s: error(decoded(s, 0), clip.root), (1 - r_share) * target, 1e-4, 1e3)
    else:
        pose_step, _ = largest_step(lambda s: error(*reconstruct(code(s, s), basis, transform, dz, n)), target, 1e-4, 1e3)
        root_step = pose_step
    coded = code(pose_step, root_step)
    achieved = clip.error(*reconstruct(coded, basis, transform, dz, n), slice(None), final=True)
    while achieved[0] > target and coded.pose_step > 1e-6:  # the sampled search missed: tighten
        coded = code(coded.pose_step * 0.9, coded.root_step * 0.9)
        achieved = clip.error(*reconstruct(coded, basis, transform, dz, n), slice(None), final=True)
    return coded, achieved


def reconstruct(coded: CodedClip, basis: ClassBasis, transform, dead_zone: float, n_frames: int):
    """Poses and root track (unscaled) from a clip's quantised coefficients."""
    coef = dequantise_curves(coded.pose_ints, coded.pose_step, transform, dead_zone, n_frames)
    poses = basis.reconstruct(coef)
    root = None
    if coded.root_ints is not None:
        root = unscale_root(dequantise_curves(coded.root_ints, coded.root_step, transform, dead_zone, n_frames))
    return poses, root
