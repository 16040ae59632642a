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

Which partition wins, and which K when none is given, is decided by bytes: the estimate of
`ratecontrol.class_bytes.ByteProxy`, calibrated once on the clips. Everything is deterministic
for a given seed.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from mocapzip.codec.pca import PcaBasis
from mocapzip.formats.errors import MocapFormatError
from mocapzip.classes.ppca import DEFAULT_VARIANCE_SHARE, PpcaModel
from mocapzip.ratecontrol.class_bytes import ByteProxy, ClipStats, merged
from mocapzip.ratecontrol.target import CodingTarget

MAX_ITERATIONS = 100
ANNEAL_COOLING = 0.7  # temperature factor per step (Hou et al. halve it; slower cooling splits more reliably)
ANNEAL_ROUNDS = 3  # membership / basis rounds per temperature
DEFAULT_MAX_K = 12
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
        """`class_bytes.union_pca(stats, weights)`: the PCA of the clips, clip i counted weights[i] times."""
        counts = self.counts * weights
        total = counts.sum()
        mean = counts @ self.means / total
        delta = self.means - mean
        m = len(mean)
        covariance = (counts @ self.covariances).reshape(m, m) + (delta * counts[:, None]).T @ delta
        return PcaBasis.from_covariance(mean, covariance / total, max(int(round(total)), 1))

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
            dims = dims or proxy.typical_components()  # subspaces as large as coded ones
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
