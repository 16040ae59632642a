"""Automatic classes: `mcz compress --classes auto[:K]` groups clips into K PCA subspaces without labels.

Entry point: `auto_classes(units, k, target) -> ["auto0" | "auto1" | ..., one per unit]`, a unit
being a whole clip or (`--segment`) one segment of a take.

Two ways of finding K classes, both from per-clip statistics (count, mean, scatter of the
codec's poses), so no frame is touched while iterating:

* k-subspaces with PPCA (thesis chapter 5, future work): every class is a PPCA model
  (`ppca.PpcaModel`, Q holding 99 % of the variance); each clip moves to the class under
  which its poses have the highest mean log density (eq. 3.13), the classes are refitted,
  and this repeats until no clip moves. Seeds: farthest-first from a seeded random clip;
  a few restarts with different seeds.
* deterministic annealing (Hou et al., section V, eq. 7 to 10): K subspaces of k
  dimensions (affine here: each has its own mean); soft memberships
  W_ij = softmax_j(-d_ij / t) of each clip's residual energy per frame d_ij (eq. 9),
  bases from the W-weighted scatter (eq. 10), the temperature lowered step by step until
  the memberships are hard and stable. Random orthonormal initial bases (seeded).

Which partition wins, and which K when none is given, is decided by bytes. The estimate
(`ByteProxy`) runs the lossy codec in pose space: per class the PCA basis, the fewest components keeping every member within the encoder's
PCA share of the budget (`ratecontrol.encode.pca_share`; the class keeps the maximum, as
`ratecontrol.encode.encode_class` does), the stored basis size (the real
`ClassBasis.encode`), and per clip the largest quantiser step meeting the budget and the
size of its coefficients in the entropy coder's layouts (zstd at a faster level). Only
the end-to-end error is modelled rather than measured: per clip, a joint-sensitivity
weight for each pose column (the decoder's inverse and forward kinematics, perturbed),
the curve from weighted truncation error to mean joint error (truncations of one PCA of
all clips, scored by `LoadedClip.error`), and how quantisation error adds to it (one
step search like the codec's, root track included). Validated against real archives in
benchmarks/classification.py. Everything is deterministic for a given seed.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from mocapzip.stages import get_stage
from mocapzip.codec.basis import ClassBasis
from mocapzip.codec.entropy.zstd import encode_ints, estimated_size
from mocapzip.codec.pca import CovarianceAccumulator, PcaBasis
from mocapzip.codec.quantise import UniformQuantiser
from mocapzip.formats.errors import MocapFormatError
from mocapzip.classes.ppca import DEFAULT_VARIANCE_SHARE, PpcaModel
from mocapzip.parallel import parallel_map
from mocapzip.ratecontrol.encode import pca_share
from mocapzip.ratecontrol.target import CodingTarget

SEARCH_STRIDE = 4  # calibration scores every 4th frame at most (MAX_CALIBRATION_FRAMES caps the count)
CALIBRATION_Q = (8, 16, 24, 32, 48, 64, 96)  # truncations scored per clip
MAX_CALIBRATION_FRAMES = 80  # frames scored per clip when calibrating (every 4th, or sparser)
ERROR_POWER = 1.5  # truncation and quantisation joint errors combine as e^p = t^p + q^p (measured)
MAX_ITERATIONS = 100
ANNEAL_COOLING = 0.7  # temperature factor per step (Hou et al. halve it; slower cooling splits more reliably)
ANNEAL_ROUNDS = 3  # membership / basis rounds per temperature
DEFAULT_MAX_K = 12
CLIP_OVERHEAD_BYTES = 40  # payload header, stream name and its index entry
CLASS_OVERHEAD_BYTES = 40
STEP_TOLERANCE = 0.01  # quantiser steps are estimated to 1 %
METHODS = ("kss", "anneal")


def parse_auto(mode: str) -> int | None | bool:
    """`auto` -> None (choose K), `auto:K` -> K; anything else -> False (not automatic)."""
    if mode == "auto":
        return None
    if mode.startswith("auto:"):
        try:
            k = int(mode[5:])
        except ValueError:
            k = 0
        if k < 1:
            raise MocapFormatError(f"--classes {mode!r}: K must be a positive integer (auto:K)")
        return k
    return False


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


def _pca(stats: list[ClipStats], weights=None) -> PcaBasis:
    """The PCA of the union of clips (weighted), with `PcaBasis.fit`'s order and sign convention."""
    return _pca_of(*merged(stats, weights))


def _pca_of(total: float, mean: np.ndarray, covariance: np.ndarray) -> PcaBasis:
    variances, components = np.linalg.eigh(covariance)
    order = np.argsort(variances)[::-1]
    variances, components = np.maximum(variances[order], 0.0), components[:, order]
    largest = np.argmax(np.abs(components), axis=0)
    components = components * np.sign(components[largest, np.arange(components.shape[1])])
    return PcaBasis(mean, components, variances, max(int(round(total)), 1))


# --- k-subspaces with PPCA (thesis chapter 5) ---------------------------------------------------


@dataclass
class _Moments:
    """Every clip's frame count (N,), per-frame mean (N, M) and covariance (N, M*M), stacked so one
    matrix product scores all clips under a model or merges any weighted set of them (k-subspaces
    and annealing do both for every class in every round)."""

    counts: np.ndarray
    means: np.ndarray
    covariances: np.ndarray
    traces: np.ndarray

    @classmethod
    def of(cls, stats: list[ClipStats]) -> "_Moments":
        counts = np.array([s.count for s in stats], np.float64)
        covariances = np.array([s.scatter.ravel() / s.count for s in stats])
        m = len(stats[0].mean)
        return cls(counts, np.array([s.mean for s in stats]), covariances, covariances[:, :: m + 1].sum(axis=1))

    def pca(self, weights: np.ndarray) -> PcaBasis:
        """`_pca(stats, weights)`: the PCA of the clips, clip i counted weights[i] times."""
        counts = self.counts * weights
        total = counts.sum()
        mean = counts @ self.means / total
        delta = self.means - mean
        m = len(mean)
        covariance = (counts @ self.covariances).reshape(m, m) + (delta * counts[:, None]).T @ delta
        return _pca_of(total, mean, covariance / total)

    def residuals(self, mean: np.ndarray, basis: np.ndarray) -> np.ndarray:
        """Mean squared residual per frame of every clip (N,) on the affine subspace (mean, basis)."""
        delta = self.means - mean
        inside = self.covariances @ (basis @ basis.T).ravel() + ((delta @ basis) ** 2).sum(axis=1)
        return np.maximum(self.traces + (delta**2).sum(axis=1) - inside, 0.0)

    def mean_log_densities(self, model: PpcaModel) -> np.ndarray:
        """`PpcaModel.mean_log_density_from_stats` of every clip (N,)."""
        v = model.components
        delta = self.means - model.mean
        outer = (v[:, None, :] * v[None, :, :]).reshape(-1, v.shape[1])  # column q: vec(v_q v_q^T)
        y2 = self.covariances @ outer + (delta @ v) ** 2  # E[y_q^2] per clip
        eps2 = np.maximum(self.traces + (delta**2).sum(axis=1) - y2.sum(axis=1), 0.0)
        return -0.5 * ((y2 / model.variances).sum(axis=1) + eps2 / model.rho) - model.log_normaliser


def kss_ppca(stats: list[ClipStats], k: int, seed: int = 0, variance_share: float = DEFAULT_VARIANCE_SHARE,
             cache: dict | None = None) -> np.ndarray:
    """Labels (N,) in 0..k-1: assign each clip to its most likely PPCA class, refit, until stable.

    `cache` keeps each fitted class's scores of all clips by its members; `plan` passes one dict
    to every K and seed on the same clips (and variance share), so each set is fitted and scored once.
    """
    n = len(stats)
    if k >= n:
        return np.arange(n)
    rng = np.random.default_rng(seed)
    moments = _Moments.of(stats)
    cache = {} if cache is None else cache

    def score(members):  # mean log density of every clip under the class of these members (N,)
        key = tuple(int(i) for i in members)
        if key not in cache:
            model = PpcaModel.from_pca(moments.pca(np.isin(np.arange(n), key).astype(float)), variance_share)
            cache[key] = moments.mean_log_densities(model)
        return cache[key]

    seeds = [int(rng.integers(n))]
    while len(seeds) < k:  # farthest first: the clip the chosen seeds explain worst
        best = np.max([score([j]) for j in seeds], axis=0)
        best[seeds] = np.inf
        seeds.append(int(np.argmin(best)))
    labels = np.argmax(np.array([score([j]) for j in seeds]), axis=0)
    labels[seeds] = np.arange(k)
    for _ in range(MAX_ITERATIONS):
        members = [np.flatnonzero(labels == j) for j in range(k)]
        scores = np.array([score(m) if len(m) else np.full(n, -np.inf) for m in members])
        empty = [j for j, m in enumerate(members) if not len(m)]
        new = np.argmax(scores, axis=0)
        for j in empty:  # re-seed an empty class with the worst explained clip
            fit_now = scores[new, np.arange(n)]
            worst = int(np.argmin(np.where(np.isin(new, empty), np.inf, fit_now)))
            new[worst] = j
        if np.array_equal(new, labels):
            break
        labels = new
    return labels


# --- deterministic annealing (Hou et al. eq. 7 to 10) --------------------------------------------


def anneal(stats: list[ClipStats], k: int, dims: int, seed: int = 0, cooling: float = ANNEAL_COOLING) -> np.ndarray:
    """Labels (N,): K affine subspaces of `dims` dimensions by deterministic annealing.

    Hou et al.'s algorithm 1 with per-frame distortions: random orthonormal bases, then
    at each temperature t a few rounds of W = softmax(-d / t) (eq. 9) and refitted
    bases (eq. 10), t shrinking by `cooling` until every clip belongs to one class and
    no clip moves. The start is hot (t above the largest distortion gap, where all classes
    coincide) and the memberships get a tiny seeded jitter each round, so classes split
    off at the critical temperatures instead of staying stuck together.
    """
    n = len(stats)
    if k >= n:
        return np.arange(n)
    rng = np.random.default_rng(seed)
    m = len(stats[0].mean)
    dims = int(min(max(dims, 1), m))
    moments = _Moments.of(stats)

    def distortions(means, bases):  # residual energy per frame of every clip in every subspace (N, K)
        return np.stack([moments.residuals(mean, basis) for mean, basis in zip(means, bases)], axis=1)

    _, global_mean, _ = merged(stats)
    means = [global_mean.copy() for _ in range(k)]
    bases = [np.linalg.qr(rng.normal(size=(m, dims)))[0] for _ in range(k)]
    d = distortions(means, bases)
    t = max(float((d.max(axis=1) - d.min(axis=1)).max()), float(d.mean()), 1e-12) * 4.0
    labels, w = None, np.full((n, k), 1.0 / k)
    for _ in range(MAX_ITERATIONS):
        for _ in range(ANNEAL_ROUNDS):
            z = -(d - d.min(axis=1, keepdims=True)) / t  # eq. 9, shifted per clip for stability
            new_w = np.exp(z) * (1.0 + 1e-3 * rng.standard_normal((n, k)))
            new_w /= new_w.sum(axis=1, keepdims=True)
            for j in range(k):  # eq. 10: the W-weighted scatter's leading eigenvectors
                if new_w[:, j].sum() < 1e-9:
                    continue
                pca = moments.pca(new_w[:, j])
                means[j], bases[j] = pca.mean, pca.components[:, :dims]
            d = distortions(means, bases)
            settled = np.abs(new_w - w).max() < 1e-4
            w = new_w
            if settled:
                break
        new = np.argmin(d, axis=1)
        hard = bool(np.all(w.max(axis=1) > 1 - 1e-6))
        if hard and labels is not None and np.array_equal(new, labels):
            break
        labels = new
        t *= cooling
    return labels


# --- the byte estimate ---------------------------------------------------------------------------


@dataclass
class ByteProxy:
    """Estimated archive bytes of a partition (see the module doc); class costs are cached.

    Errors are measured in a weighted pose space: column c of clip i counts with weight
    weights[i, c], the mean squared joint displacement (cm^2, over joints) per unit change
    of that column, found by perturbing each column on a few frames and running the
    decoder's inverse and forward kinematics. (Unweighted, a bone-axis column that turns a
    whole leg would count like a position column that moves one joint a little.)
    tolerance[i, s]: the weighted RMS error per frame clip i may keep after truncation to
    meet PCA share s of the budget (`_shares`: the encoder's one), read off the clip's measured truncation curve
    (`curves[i]`: log weighted RMS error, log mean joint error). Truncation and quantisation
    errors combine as e^p = t^p + (gamma_i u)^p (p = ERROR_POWER; t the truncation's joint
    error, u the weighted RMS quantisation error, gamma_i measured at the codec's step for
    the encoder's share, with the root track quantised alongside).
    """

    poses: list[np.ndarray]
    target: CodingTarget
    tolerance: np.ndarray  # (N, shares)
    weights: np.ndarray  # (N, M)
    curves: list[tuple[np.ndarray, np.ndarray]]
    gamma: np.ndarray  # (N,)
    stats: list[ClipStats]
    _cache: dict = field(default_factory=dict)
    details: dict = field(default_factory=dict)  # members -> {"share", "components", "basis_bytes", "clip_bytes"}

    @classmethod
    def calibrate(cls, clips, target: CodingTarget, stats: list[ClipStats] | None = None, jobs: int = 1) -> "ByteProxy":
        poses = [c.poses for c in clips]
        stats = stats or [ClipStats.of(p) for p in poses]
        _SHARED.update(clips=clips, pca=_pca(stats), target=target)
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

    def _class_bytes(self, members: tuple[int, ...]) -> int:
        target = self.target
        transform = get_stage("transform", target.transform)
        pca = _pca([self.stats[i] for i in members])
        v = pca.components
        m = len(pca.mean)
        residual, gains = [], []
        for i in members:
            gram = v.T @ (self.weights[i][:, None] * v)  # weighted Gram of the components
            residual.append(_weighted_truncation(self.stats[i], pca.mean, v, gram))
            gains.append(np.diag(gram).copy())
        residual = np.array(residual)  # (members, M + 1) weighted mean squared error per frame
        shares = _shares(target)
        qs = []
        for s in range(len(shares)):
            allowed = self.tolerance[list(members), s] ** 2
            qs.append(max(int(np.argmax(r <= a)) if np.any(r <= a) else m for r, a in zip(residual, allowed)))
        # the transform works per curve: transform each clip's curves once, for the most components any share keeps
        curves = [transform.forward((self.poses[i] - pca.mean) @ v[:, :max(max(qs), 1)]) for i in members]
        best = None
        for share, q in zip(shares, qs):
            basis = _basis_bytes(pca, q, target) + CLASS_OVERHEAD_BYTES
            clip_bytes = sum(_clip_bytes(curves[row][:, :q], gains[row][:q],
                                         self.quantisation_allowance(i, residual[row, q]), target.dead_zone)
                             for row, i in enumerate(members))
            if best is None or basis + clip_bytes < best:
                best = basis + clip_bytes
                self.details[members] = {"share": share, "components": q, "basis_bytes": basis,
                                         "clip_bytes": clip_bytes}
        return int(best)


_SHARED: dict = {}  # what forked calibration workers read


def _basis_bytes(pca: PcaBasis, q: int, target: CodingTarget) -> int:
    """The size of a class basis of q components, built as `ratecontrol.encode.encode_class` builds
    it, its integers in zstd layouts like the clip estimates (fast; the archive's range coder is
    about 7 % smaller): header, steps, and two length-prefixed ints blobs."""
    steps = ClassBasis.steps_for(pca.variances[:q], target.error_cm, target.basis_precision)
    mean_ints, ints = ClassBasis.quantised(pca.mean, pca.components[:, :q], steps).integers()
    return 8 + 4 * q + 8 + len(encode_ints(mean_ints)) + len(encode_ints(ints))


def _shares(target: CodingTarget) -> tuple[float, ...]:
    """The PCA shares of the error budget a class is estimated at: the encoder's one."""
    return (pca_share(target),)


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
    from mocapzip.motion.kinematics import forward
    from mocapzip.representations.weighted import channels_from_weighted

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
    """One clip's (share tolerances, column weights, truncation curve, gamma), measured end to end.

    Truncations of the PCA of all clips give pairs (weighted pose RMS error, mean joint
    error): the truncation curve; each PCA share's target is read off it. Then, keeping the
    components of the encoder's share (`_shares`' one), the codec's step search (`search.largest_step`, the root
    step a fixed share of the pose step as in the codec) finds the step meeting the whole budget, and gamma
    follows from the combination rule (see ByteProxy).
    """
    from mocapzip.codec.clip_stream import scale_root, unscale_root
    from mocapzip.ratecontrol.encode import ROOT_STEP_RATIO
    from mocapzip.ratecontrol.search import largest_step

    clip, pca, coding = _SHARED["clips"][index], _SHARED["pca"], _SHARED["target"]
    weights = _column_weights(clip)
    n = len(clip.poses)
    stride = max(SEARCH_STRIDE, -(-n // MAX_CALIBRATION_FRAMES))
    frames = slice(None, None, stride)
    coef_all = (clip.poses - pca.mean) @ pca.components
    coef, poses = coef_all[frames], clip.poses[frames]
    root = None if clip.root is None else clip.root[frames]
    m = pca.components.shape[1]
    target = coding.error_cm
    targets = np.array(_shares(coding)) * target

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
    shares = np.exp(np.interp(np.log(targets), lj, lp))
    below, above = np.log(targets) < lj[0], np.log(targets) > lj[-1]  # outside: proportional
    shares[below] = pose_err[-1] * targets[below] / joint_err[-1]
    shares[above] = pose_err[0] * targets[above] / joint_err[0]
    # the encoder's share's components, then the step search on pose and root together
    aim = np.log(targets[0])
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
    return shares, weights, (lp, lj), gamma


def _clip_bytes(curves: np.ndarray, gains: np.ndarray, allowed: float, dead_zone: float) -> int:
    """Bytes of a clip's quantised curves at the largest step keeping their weighted quantisation
    error within `allowed` (mean squared per frame; curve k's error counts gains[k] times)."""
    if curves.size == 0:
        return CLIP_OVERHEAD_BYTES
    step = _largest_step(curves, gains, allowed * len(curves), dead_zone)
    return estimated_size(UniformQuantiser(step, dead_zone).quantise(curves)) + CLIP_OVERHEAD_BYTES


def _largest_step(curves: np.ndarray, gains: np.ndarray, budget: float, dead_zone: float) -> float:
    """The largest step in [1e-4, 1e3] (to within STEP_TOLERANCE in log step) whose weighted
    squared quantisation error, summed over the curves, stays within `budget`.

    The error grows about like a power of the step, so regula falsi on log error against
    log step (Illinois variant, the bracket always holding a step that meets the budget and
    one that does not) takes a handful of trials where plain bisection took 16. The bracket
    starts at the step where no coefficient can be off by more than the budget allows.
    """
    if budget <= 0:
        return 1e-4

    def excess(log_step):  # log(error / budget): <= 0 meets the budget
        q = UniformQuantiser(float(np.exp(log_step)), dead_zone)
        error = float((((curves - q.dequantise(q.quantise(curves))) ** 2).sum(axis=0) * gains).sum())
        return float(np.log(max(error, 1e-300) / budget))

    hi = np.log(1e3)
    f_hi = excess(hi)
    if f_hi <= 0:
        return 1e3
    safe = np.sqrt(budget / max(float(gains.sum()) * len(curves), 1e-300)) / (0.5 + dead_zone)
    lo = float(np.clip(np.log(safe), np.log(1e-4), hi))
    f_lo = excess(lo)
    if f_lo > 0:
        return float(np.exp(lo))
    kept = 0  # which end the last trials kept: halve its value when kept twice (Illinois)
    while hi - lo > STEP_TOLERANCE:
        x = lo - f_lo * (hi - lo) / (f_hi - f_lo)
        x = min(max(x, lo + 0.01 * (hi - lo)), hi - 0.01 * (hi - lo))
        f = excess(x)
        if f <= 0:
            lo, f_lo = x, f
            f_hi = f_hi / 2 if kept == 1 else f_hi
            kept = 1
        else:
            hi, f_hi = x, f
            f_lo = f_lo / 2 if kept == -1 else f_lo
            kept = -1
    return float(np.exp(lo))


# --- choosing the classes ------------------------------------------------------------------------


@dataclass
class AutoPlan:
    """What `plan` decided: labels per clip, K, method and the estimates behind the choice."""

    labels: np.ndarray
    k: int
    method: str
    estimated_bytes: int
    candidates: list[dict]  # {"k", "method", "seed", "bytes"} for every partition tried


def plan(clips, k: int | None, target: CodingTarget, *, max_k: int | None = None, seed: int = 0, restarts: int = 3,
         methods=METHODS, proxy: ByteProxy | None = None, jobs: int = 1) -> AutoPlan:
    """Partition clips of one pose width into classes; fewest estimated bytes wins.

    With `k`, only K (or fewer when clips are few) is tried; without, K = 1, 2, ... up to
    `max_k` (default min(clips, 12)), stopping once two K in a row do worse than the best.
    Each K is searched with k-subspaces (`restarts` seeds, cheap: fitted classes are cached);
    annealing, a hundred eigendecompositions per class and run, is then tried at the best K
    only. (On 74 CMU clips, subjects 02 07 09 35 64, annealing lost to k-subspaces at every
    K = 2..9 by 3 to 12 %; on all 118 CMU clips it won at the K k-subspaces chose, by 10 %.)
    Without "kss" in `methods`, annealing searches every K instead.
    """
    n = len(clips)
    proxy = proxy or ByteProxy.calibrate(clips, target, jobs=jobs)
    stats = proxy.stats
    ks = [min(k, n)] if k else list(range(1, min(n, max_k or DEFAULT_MAX_K) + 1))
    search = "kss" if "kss" in methods else "anneal"
    candidates, tried, fitted = [], {}, {}  # tried: partition -> (bytes, method)
    dims = None

    def consider(method: str, kk: int, s: int) -> None:
        nonlocal dims
        if method == "single":
            labels = np.zeros(n, int)
        elif method == "kss":
            labels = kss_ppca(stats, kk, s, cache=fitted)
        else:
            dims = dims or _anneal_dims(stats, proxy)
            labels = anneal(stats, kk, dims, s)
        labels = _canonical(labels)
        size = proxy.partition_bytes(labels)
        candidates.append({"k": int(labels.max() + 1), "method": method, "seed": s, "bytes": size})
        tried.setdefault(tuple(labels), (size, method))

    def best() -> tuple:  # the first partition with the fewest bytes
        return min(tried, key=lambda labels: tried[labels][0])

    leader, worse = None, 0
    for kk in ks:
        runs = restarts if search == "kss" else max(1, restarts // 2)
        for method, s in [("single", seed)] if kk == 1 else [(search, seed + r) for r in range(runs)]:
            consider(method, kk, s)
        if best() != leader:
            leader, worse = best(), 0
        else:
            worse += 1
            if k is None and worse >= 2:
                break
    if search == "kss" and "anneal" in methods and max(leader) > 0:
        for r in range(max(1, restarts // 2)):
            consider("anneal", max(leader) + 1, seed + r)
    labels = best()
    size, method = tried[labels]
    return AutoPlan(np.array(labels), int(max(labels) + 1), method, int(size), candidates)


def _anneal_dims(stats, proxy: ByteProxy) -> int:
    """Subspace dimension for annealing: the median over clips of the components one class of
    everything needs to meet the encoder's PCA share (`_shares`' one: tolerance column 0), so the
    subspaces are as large as coded ones."""
    pca = _pca(stats)
    need = []
    for i, st in enumerate(stats):
        gram = pca.components.T @ (proxy.weights[i][:, None] * pca.components)
        residual = _weighted_truncation(st, pca.mean, pca.components, gram)
        hits = np.flatnonzero(residual <= proxy.tolerance[i, 0] ** 2)
        need.append(int(hits[0]) if hits.size else len(residual) - 1)
    return max(int(np.median(need)), 1)


def _canonical(labels) -> np.ndarray:
    """Renumber classes by first appearance (clips are in stored-path order): same partition, same labels."""
    labels = np.asarray(labels)
    order = {}
    for value in labels:
        order.setdefault(int(value), len(order))
    return np.array([order[int(v)] for v in labels], int)


def auto_classes(clips, k: int | None, target: CodingTarget, *, max_k: int | None = None, seed: int = 0,
                 restarts: int = 3, jobs: int = 1, report: dict | None = None) -> list[str]:
    """The automatic class name ("auto0", "auto1", ...) of each clip, in the order of `clips`.

    `clips` are LoadedClips in the archive's representation (lossy mode), whole takes or
    segments of takes (so names go by position, not by stored path). Clips whose
    poses have different widths (different skeleton layouts) cannot share a basis: each
    width is partitioned on its own (K applies to each) and numbering continues across
    them. `report`, if given, receives the plan of each width group (JSON-able).
    """
    by_width: dict[int, list[int]] = {}
    for i, clip in enumerate(clips):
        by_width.setdefault(clip.poses.shape[1], []).append(i)
    names = [""] * len(clips)
    offset = 0
    plans = []
    for width, indices in sorted(by_width.items(), key=lambda kv: kv[1][0]):
        group = [clips[i] for i in indices]
        result = plan(group, k, target, max_k=max_k, seed=seed, restarts=restarts, jobs=jobs)
        for i, label in zip(indices, result.labels):
            names[i] = f"auto{offset + int(label)}"
        plans.append({"width": width, "clips": len(indices), "k": result.k, "method": result.method,
                      "estimated_bytes": result.estimated_bytes, "candidates": result.candidates})
        offset += result.k
    if report is not None:
        report["groups"] = plans
    return names
