"""What a class of clips would cost in bytes: the estimate `--classes auto` partitions by.

`ByteProxy.calibrate` measures each clip once; `ByteProxy.class_bytes(members)` then estimates
a class from per-clip statistics (`ClipStats`: count, mean, scatter of the codec's poses), so
no frame is touched while a partition search tries hundreds of classes. It runs the lossy
codec in pose space: per class the PCA basis (`PcaBasis.from_covariance`), the fewest
components keeping every member within the encoder's PCA share of the budget
(`encode.pca_share`; the class keeps the maximum, as `encode.encode_class` does), the stored
basis (`ClassBasis` as quantised, its header, its integers' size), and per clip the largest
quantiser step meeting the budget (`search.largest_step_power_law`) and the size of its
coefficients in the entropy coder's layouts (zstd at a faster level). Only the end-to-end
error is modelled rather than measured: per clip, a joint-sensitivity weight for each pose
column (the decoder's inverse and forward kinematics, perturbed), the curve from weighted
truncation error to mean joint error (truncations of one PCA of all clips, scored by
`LoadedClip.error`), and how quantisation error adds to it (one step search like the codec's,
`search.largest_step`, root track included). Validated against real archives in
benchmarks/classification.py. Everything is deterministic.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from mocapzip.codec.basis import ClassBasis
from mocapzip.codec.clip_stream import scale_root, unscale_root
from mocapzip.codec.entropy.zstd import encode_ints, estimated_size
from mocapzip.codec.pca import CovarianceAccumulator, PcaBasis
from mocapzip.codec.quantise import UniformQuantiser
from mocapzip.motion.kinematics import forward
from mocapzip.parallel import parallel_map, worker_state
from mocapzip.ratecontrol.encode import ROOT_STEP_RATIO, pca_share
from mocapzip.ratecontrol.search import largest_step, largest_step_power_law
from mocapzip.ratecontrol.target import CodingTarget
from mocapzip.representations.weighted import channels_from_weighted
from mocapzip.stages import get_stage

# Calibration scores at most MAX_CALIBRATION_FRAMES frames of a clip, every CALIBRATION_STRIDE-th
# or sparser: a curve fitted on few frames, where `encode.SEARCH_STRIDE` (8) samples the searches
# of a clip being coded, which a final check on every frame then corrects. They differ only on
# clips of 560 frames or fewer (longer ones the cap thins out more than either). Calibrating
# every 8th frame at most instead moved every partition's estimate, though not the K chosen
# (one class of cmu/09: 6,389 -> 6,414 B; of cmu/07 and 35: 20,794 -> 21,118 B), and the
# estimates are stored (meta `auto_classes`).
CALIBRATION_STRIDE = 4
MAX_CALIBRATION_FRAMES = 80
CALIBRATION_Q = (8, 16, 24, 32, 48, 64, 96)  # truncations scored per clip
ERROR_POWER = 1.5  # truncation and quantisation joint errors combine as e^p = t^p + q^p (measured)
CLIP_OVERHEAD_BYTES = 40  # payload header, stream name and its index entry
CLASS_OVERHEAD_BYTES = 48  # stream name, index entry and the lengths of the two integer blobs
STEP_TOLERANCE = 0.01  # quantiser steps are estimated to 1 % (in log step)
STEP_RANGE = (1e-4, 1e3)  # quantiser steps searched


@dataclass
class ClipStats:
    """A clip's pose statistics: frames, mean (M,), scatter about the mean (M, M)."""

    count: int
    mean: np.ndarray
    scatter: np.ndarray

    @classmethod
    def of(cls, poses: np.ndarray) -> "ClipStats":
        acc = CovarianceAccumulator(poses.shape[1])
        acc.add(poses)
        return cls(acc.count, acc.mean, acc.covariance * acc.count)


def merged(stats: list[ClipStats], weights=None) -> tuple[float, np.ndarray, np.ndarray]:
    """(weight, mean, covariance) of the union of clips, each counted `weights[i]` times."""
    w = np.ones(len(stats)) if weights is None else np.asarray(weights, np.float64)
    counts = np.array([s.count for s in stats]) * w
    total = counts.sum()
    means = np.array([s.mean for s in stats])
    mean = counts @ means / total
    scatter = sum(wi * s.scatter for wi, s in zip(w, stats) if wi > 0)
    delta = means - mean
    scatter = scatter + (delta * counts[:, None]).T @ delta
    return total, mean, scatter / total


def union_pca(stats: list[ClipStats], weights=None) -> PcaBasis:
    """The PCA of the union of clips (clip i counted weights[i] times), as `PcaBasis.fit` orders and signs it."""
    total, mean, covariance = merged(stats, weights)
    return PcaBasis.from_covariance(mean, covariance, max(int(round(total)), 1))


@dataclass
class ByteProxy:
    """Estimated archive bytes of a partition (see the module doc); class costs are cached.

    Errors are measured in a weighted pose space: column c of clip i counts with weight
    weights[i, c], the mean squared joint displacement (cm^2, over joints) per unit change
    of that column, found by perturbing each column on a few frames and running the
    decoder's inverse and forward kinematics. (Unweighted, a bone-axis column that turns a
    whole leg would count like a position column that moves one joint a little.)
    tolerance[i]: the weighted RMS error per frame clip i may keep after truncation to meet
    the encoder's PCA share of the budget, read off the clip's measured truncation curve
    (`curves[i]`: log weighted RMS error, log mean joint error). Truncation and quantisation
    errors combine as e^p = t^p + (gamma_i u)^p (p = ERROR_POWER; t the truncation's joint
    error, u the weighted RMS quantisation error, gamma_i measured at the codec's step for
    the encoder's share, with the root track quantised alongside).
    """

    poses: list[np.ndarray]
    target: CodingTarget
    tolerance: np.ndarray  # (N,)
    weights: np.ndarray  # (N, M)
    curves: list[tuple[np.ndarray, np.ndarray]]
    gamma: np.ndarray  # (N,)
    stats: list[ClipStats]
    _cache: dict = field(default_factory=dict)
    details: dict = field(default_factory=dict)  # members -> {"components", "basis_bytes", "clip_bytes"}

    @classmethod
    def calibrate(cls, clips, target: CodingTarget, jobs: int = 1) -> "ByteProxy":
        poses = [c.poses for c in clips]
        stats = [ClipStats.of(p) for p in poses]
        _SHARED.update(clips=clips, pca=union_pca(stats), target=target)
        try:
            rows = parallel_map(_calibrate_clip, range(len(clips)), jobs)
        finally:
            _SHARED.clear()
        return cls(poses, target, np.array([r[0] for r in rows]), np.array([r[1] for r in rows]),
                   [r[2] for r in rows], np.array([r[3] for r in rows]), stats)

    def joint_error(self, i: int, weighted_ms: float) -> float:
        """Clip i's mean joint error (cm) estimated from a truncation's weighted mean squared error."""
        lp, lj = self.curves[i]
        x = 0.5 * np.log(max(weighted_ms, 1e-300))
        if x <= lp[0]:
            return float(np.exp(lj[0] + x - lp[0]))
        if x >= lp[-1]:
            return float(np.exp(lj[-1] + x - lp[-1]))
        return float(np.exp(np.interp(x, lp, lj)))

    def quantisation_allowance(self, i: int, weighted_ms: float) -> float:
        """Weighted mean squared quantisation error per frame clip i may add to this truncation."""
        target, t = self.target.error_cm, self.joint_error(i, weighted_ms)
        if t >= target:
            return 0.0
        return float(((target**ERROR_POWER - t**ERROR_POWER) ** (1 / ERROR_POWER) / self.gamma[i]) ** 2)

    def class_bytes(self, members) -> int:
        key = tuple(sorted(int(i) for i in members))
        if key not in self._cache:
            self._cache[key] = self._class_bytes(key)
        return self._cache[key]

    def partition_bytes(self, labels) -> int:
        labels = np.asarray(labels)
        return int(sum(self.class_bytes(np.flatnonzero(labels == j)) for j in np.unique(labels)))

    def typical_components(self) -> int:
        """The median over clips of the components one class of every clip needs for each to meet
        its tolerance (at least 1): how large a coded class's subspace is."""
        members = tuple(range(len(self.stats)))
        _, _, needed = self._truncations(members, union_pca(self.stats))
        return max(int(np.median(needed)), 1)

    def _truncations(self, members: tuple[int, ...], pca: PcaBasis) -> tuple[np.ndarray, list, list[int]]:
        """Per member of a class with this PCA: its weighted mean squared error per frame keeping
        q = 0..M components (members, M + 1), the weighted gain of each component, and the fewest
        components that meet its tolerance."""
        v = pca.components
        residual, gains = [], []
        for i in members:
            gram = v.T @ (self.weights[i][:, None] * v)  # weighted Gram of the components
            residual.append(_weighted_truncation(self.stats[i], pca.mean, v, gram))
            gains.append(np.diag(gram).copy())
        allowed = self.tolerance[list(members)] ** 2
        needed = [int(np.argmax(r <= a)) if np.any(r <= a) else len(r) - 1 for r, a in zip(residual, allowed)]
        return np.array(residual), gains, needed

    def _class_bytes(self, members: tuple[int, ...]) -> int:
        target = self.target
        transform = get_stage("transform", target.transform)
        pca = union_pca([self.stats[i] for i in members])
        residual, gains, needed = self._truncations(members, pca)
        q = max(needed)
        basis = _basis_bytes(pca, q, target) + CLASS_OVERHEAD_BYTES
        # each clip's curves on the q components (on one at q = 0, for the transform; none is kept)
        curves = [transform.forward((self.poses[i] - pca.mean) @ pca.components[:, :max(q, 1)]) for i in members]
        clip_bytes = sum(_clip_bytes(curves[row][:, :q], gains[row][:q],
                                     self.quantisation_allowance(i, residual[row, q]), target.dead_zone)
                         for row, i in enumerate(members))
        self.details[members] = {"components": q, "basis_bytes": basis, "clip_bytes": clip_bytes}
        return int(basis + clip_bytes)


_SHARED = worker_state(__name__)  # what forked calibration workers read


def _basis_bytes(pca: PcaBasis, q: int, target: CodingTarget) -> int:
    """The size of a class basis of q components quantised as `encode.encode_class` stores it: its
    header, and its integers in zstd layouts like the clip estimates (the archive's range coder
    is about 7 % smaller)."""
    steps = ClassBasis.steps_for(pca.variances[:q], target.error_cm, target.basis_precision)
    basis = ClassBasis.quantised(pca.mean, pca.components[:, :q], steps)
    return len(basis.header()) + sum(len(encode_ints(ints)) for ints in basis.integers())


def _weighted_truncation(stat: ClipStats, mean: np.ndarray, v: np.ndarray, gram: np.ndarray) -> np.ndarray:
    """Weighted mean squared residual per frame of a clip when keeping q = 0..M components.

    With c_f = V^T (x_f - mean) and C = sum_f c_f c_f^T, the residual of frame f is the
    part of c_f beyond q, so its weighted energy summed over frames is the sum of
    (C * G)[k, l] over k, l >= q: a 2-D suffix sum, from the clip's statistics alone.
    """
    delta = stat.mean - mean
    second = stat.scatter + stat.count * np.outer(delta, delta)
    p = (v.T @ second @ v) * gram
    suffix = p[::-1, ::-1].cumsum(axis=0).cumsum(axis=1)[::-1, ::-1]
    return np.maximum(np.concatenate([np.diag(suffix), [0.0]]) / stat.count, 0.0)


def _column_weights(clip, frames: int = 4, delta: float = 1e-3) -> np.ndarray:
    """Mean squared joint displacement (over joints, cm^2) per unit squared change of each pose column.

    Each column is nudged by `delta` on a few frames spread over the clip, the result decoded
    like `mcz decompress` (representation inverse, forward kinematics), and compared with the
    undisturbed decode. One batch: (M + 1) x frames poses.
    """
    m = clip.poses.shape[1]
    if clip.positions is None:
        return np.ones(m)
    index = np.unique(np.linspace(0, len(clip.poses) - 1, frames).astype(int))
    batch = np.repeat(clip.poses[index][:, None, :], m + 1, axis=1)
    batch[:, 1:, :] += np.eye(m) * delta
    root = None if clip.root is None else np.repeat(clip.root[index], m + 1, axis=0)
    values = channels_from_weighted(clip.model, clip.representation, clip.layout, batch.reshape(-1, m), root,
                                    clip.encoded.params, clip.axis_weight_cm)
    positions = forward(clip.model, values, clip.layout).positions.reshape(len(index), m + 1, -1, 3)
    moved = positions[:, 1:] - positions[:, :1]
    return np.maximum((moved**2).sum(axis=-1).mean(axis=-1).mean(axis=0) / delta**2, 0.0)


def _calibrate_clip(index: int):
    """One clip's (tolerance, column weights, truncation curve, gamma), measured end to end.

    Truncations of the PCA of all clips give pairs (weighted pose RMS error, mean joint
    error): the truncation curve; the tolerance, the weighted error at the encoder's PCA
    share of the budget, is read off it. Then, keeping the components that share needs, the
    codec's step search (`search.largest_step`, the root step a fixed share of the pose step as
    in the codec) finds the step meeting the whole budget, and gamma follows from the
    combination rule (see ByteProxy).
    """
    clip, pca, coding = _SHARED["clips"][index], _SHARED["pca"], _SHARED["target"]
    weights = _column_weights(clip)
    n = len(clip.poses)
    stride = max(CALIBRATION_STRIDE, -(-n // MAX_CALIBRATION_FRAMES))
    frames = slice(None, None, stride)
    coef_all = (clip.poses - pca.mean) @ pca.components
    coef, poses = coef_all[frames], clip.poses[frames]
    root = None if clip.root is None else clip.root[frames]
    m = pca.components.shape[1]
    target = coding.error_cm
    share_target = pca_share(coding) * target

    def weighted_rms(a, b):
        return float(np.sqrt((((a - b) ** 2) * weights).sum(axis=1).mean()))

    def joint_error(approx, root_approx):
        if clip.positions is None:
            return weighted_rms(poses, approx)
        return clip.error(approx, root_approx, frames)[0]

    pose_err, joint_err, qs = [], [], []
    for q in [q for q in CALIBRATION_Q if q < m]:
        approx = pca.mean + coef[:, :q] @ pca.components[:, :q].T
        rms, joint = weighted_rms(poses, approx), joint_error(approx, root)
        if rms > 0 and joint > 0:
            pose_err.append(rms)
            joint_err.append(joint)
            qs.append(q)
    if len(pose_err) < 2:  # (nearly) nothing to truncate: a straight line through the one point
        pose_err, joint_err, qs = [1.0, 2.0], [target, 2 * target], [m, max(m - 1, 1)]
    lp = np.log(pose_err)[::-1]
    lj = np.maximum.accumulate(np.log(joint_err)[::-1])  # increasing errors, monotone
    aim = np.log(share_target)
    if aim < lj[0]:  # outside the curve: proportional
        tolerance = pose_err[-1] * share_target / joint_err[-1]
    elif aim > lj[-1]:
        tolerance = pose_err[0] * share_target / joint_err[0]
    else:
        tolerance = np.exp(np.interp(aim, lj, lp))
    # the components of the encoder's share, then the step search on pose and root together
    q0 = int(round(np.exp(np.interp(aim, lj, np.log(qs)[::-1])))) if aim >= lj[0] else qs[-1]
    q0 = min(max(q0, 1), m)
    transform = get_stage("transform", coding.transform)
    truncated = pca.mean + coef[:, :q0] @ pca.components[:, :q0].T
    t0 = joint_error(truncated, root)
    curves = transform.forward(coef_all[:, :q0])
    root_curves = None if clip.root is None else transform.forward(scale_root(clip.root))
    dz, cache = coding.dead_zone, {}

    def error(step):
        quantiser = UniformQuantiser(step, dz)
        decoded = transform.inverse(quantiser.dequantise(quantiser.quantise(curves)), n)[frames]
        approx = pca.mean + decoded @ pca.components[:, :q0].T
        root_quantiser = UniformQuantiser(step * ROOT_STEP_RATIO, dz)
        root_approx = None if root_curves is None else unscale_root(
            transform.inverse(root_quantiser.dequantise(root_quantiser.quantise(root_curves)), n)[frames])
        cache[step] = weighted_rms(truncated, approx)
        return joint_error(approx, root_approx)

    gamma = 1.0
    if t0 < target:
        step, achieved = largest_step(error, target, 1e-3, 1e2, rel_tol=0.05)
        if step not in cache:
            error(step)
        u = cache[step]
        if u > 0 and achieved <= target:
            # solve achieved^p = t0^p + (gamma u)^p for gamma (with the error actually achieved)
            rest = max(achieved**ERROR_POWER - t0**ERROR_POWER, (0.05 * achieved) ** ERROR_POWER)
            gamma = rest ** (1 / ERROR_POWER) / u
    return tolerance, weights, (lp, lj), gamma


def _clip_bytes(curves: np.ndarray, gains: np.ndarray, allowed: float, dead_zone: float) -> int:
    """Bytes of a clip's quantised curves at the largest step keeping their weighted quantisation
    error within `allowed` (mean squared per frame; curve k's error counts gains[k] times).

    The step search starts where no coefficient can be off by more than the budget allows. It
    is not `search.largest_step`, which fits the floor an end-to-end error keeps at the finest
    step: this error is the quantiser's alone, a power of the step, which regula falsi in log
    space solves in half the scores. (`largest_step` on its square root, to the same 1 %, took
    558 scores against 280 for a plan of cmu/09, 2,136 against 1,016 for cmu/07 and 35, and moved
    the stored estimates by a few bytes: one class of cmu/09, 6,389 -> 6,391 B.)
    """
    if curves.size == 0:
        return CLIP_OVERHEAD_BYTES
    budget = allowed * len(curves)

    def error(step: float) -> float:
        q = UniformQuantiser(step, dead_zone)
        return float((((curves - q.dequantise(q.quantise(curves))) ** 2).sum(axis=0) * gains).sum())

    safe = np.sqrt(budget / max(float(gains.sum()) * len(curves), 1e-300)) / (0.5 + dead_zone)
    step = largest_step_power_law(error, budget, *STEP_RANGE, safe, STEP_TOLERANCE)
    return estimated_size(UniformQuantiser(step, dead_zone).quantise(curves)) + CLIP_OVERHEAD_BYTES
