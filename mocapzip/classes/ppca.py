"""Probabilistic PCA class models (thesis section 3.2.4, eq. 3.10 to 3.13; Moghaddam and Pentland).

A class Omega of poses (rows of M values) is modelled by its mean, its first Q
principal directions V_Q with variances lambda_1..lambda_Q, and one "noise"
variance rho for the M - Q remaining directions:

    Q     = the fewest components holding `variance_share` (99 %) of the variance
    rho   = (1 / (M - Q)) * sum_{i > Q} lambda_i                     (the mean of the rest)
    y     = V_Q^T (x - mean)                                          (projection)
    eps^2 = ||x - mean||^2 - sum_i y_i^2                              (eq. 3.11)
    d     = sum_i y_i^2 / lambda_i + eps^2 / rho                      (eq. 3.12)
    log P = -d / 2 - (Q / 2) log(2 pi) - (1 / 2) sum_i log lambda_i
            - ((M - Q) / 2) log(2 pi rho)                             (log of eq. 3.13)

The model is fitted from streamed statistics (`CovarianceAccumulator`), so a class
can hold more frames than memory. rho is floored (RHO_FLOOR times the total
variance) so that a class whose poses span fewer than M dimensions, e.g. one short
clip, still has a finite density.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from mocapzip.codec.pca import CovarianceAccumulator, PcaBasis

DEFAULT_VARIANCE_SHARE = 0.99  # thesis: Q_k holds 99 % of the class's variance
RHO_FLOOR = 1e-9  # relative to the total variance: keeps log P finite for degenerate classes
_LOG_2PI = float(np.log(2.0 * np.pi))


def components_for_share(variances: np.ndarray, share: float) -> int:
    """The fewest leading components whose variances sum to at least `share` of the total (>= 1)."""
    variances = np.maximum(np.asarray(variances, np.float64), 0.0)
    total = variances.sum()
    if total <= 0:
        return 1
    cumulative = np.cumsum(variances) / total
    return int(min(np.searchsorted(cumulative, share - 1e-12) + 1, len(variances)))


@dataclass
class PpcaModel:
    """One class's PPCA density: mean (M,), components (M, Q), variances (Q,), rho."""

    mean: np.ndarray
    components: np.ndarray
    variances: np.ndarray
    rho: float
    count: int = 0

    @classmethod
    def fit(cls, poses, variance_share: float = DEFAULT_VARIANCE_SHARE, q: int | None = None) -> "PpcaModel":
        """Fit from a (frames x M) array, or from a list of such arrays (one class of clips)."""
        arrays = [poses] if isinstance(poses, np.ndarray) else list(poses)
        accumulator = CovarianceAccumulator(np.atleast_2d(arrays[0]).shape[1])
        for array in arrays:
            accumulator.add(array)
        return cls.from_accumulator(accumulator, variance_share, q)

    @classmethod
    def from_accumulator(cls, accumulator: CovarianceAccumulator, variance_share: float = DEFAULT_VARIANCE_SHARE,
                         q: int | None = None) -> "PpcaModel":
        return cls.from_pca(PcaBasis.fit(accumulator), variance_share, q)

    @classmethod
    def from_pca(cls, pca: PcaBasis, variance_share: float = DEFAULT_VARIANCE_SHARE,
                 q: int | None = None) -> "PpcaModel":
        """Keep Q components (`q`, or the fewest holding `variance_share`); rho from the rest."""
        variances = pca.variances
        m = len(variances)
        if q is None:
            q = components_for_share(variances, variance_share)
        q = int(min(max(q, 1), m))
        total = float(variances.sum())
        floor = max(RHO_FLOOR * total, np.finfo(np.float64).tiny)
        kept = np.maximum(variances[:q], floor)
        rho = float(variances[q:].mean()) if q < m else floor
        return cls(pca.mean.copy(), pca.components[:, :q].copy(), kept, max(rho, floor), pca.count)

    @property
    def dim(self) -> int:
        return self.mean.shape[0]

    @property
    def q(self) -> int:
        return self.components.shape[1]

    def project(self, poses) -> tuple[np.ndarray, np.ndarray]:
        """(y, eps^2): coordinates on the Q components (N, Q) and squared residual norms (N,), eq. 3.11."""
        centred = np.atleast_2d(np.asarray(poses, np.float64)) - self.mean
        y = centred @ self.components
        eps2 = np.maximum(np.einsum("ij,ij->i", centred, centred) - np.einsum("ij,ij->i", y, y), 0.0)
        return y, eps2

    def distance(self, poses) -> np.ndarray:
        """Mahalanobis-like distance d of each pose (eq. 3.12)."""
        y, eps2 = self.project(poses)
        return (y**2 / self.variances).sum(axis=1) + eps2 / self.rho

    @property
    def log_normaliser(self) -> float:
        """log of the denominator of eq. 3.13."""
        m, q = self.dim, self.q
        return 0.5 * (q * _LOG_2PI + np.log(self.variances).sum() + (m - q) * (_LOG_2PI + np.log(self.rho)))

    def log_density(self, poses) -> np.ndarray:
        """log P(x | Omega) of each pose (N,), the log of eq. 3.13."""
        return -0.5 * self.distance(poses) - self.log_normaliser

    def mean_log_density_from_stats(self, count: int, mean: np.ndarray, scatter: np.ndarray) -> float:
        """The mean of log_density over a set of poses given only their count, mean and scatter
        (sum of outer products about their mean): what clip assignment needs, without the frames."""
        delta = mean - self.mean
        second = scatter / count + np.outer(delta, delta)  # E[(x - mu)(x - mu)^T]
        projected = ((second @ self.components) * self.components).sum(axis=0)  # E[y_i^2]
        eps2 = max(float(np.trace(second) - projected.sum()), 0.0)
        d = float((projected / self.variances).sum() + eps2 / self.rho)
        return -0.5 * d - self.log_normaliser


def fit_class_models(poses_by_class: dict[str, list[np.ndarray]], variance_share: float = DEFAULT_VARIANCE_SHARE
                     ) -> dict[str, PpcaModel]:
    """One PpcaModel per class name from its clips' pose arrays (sorted by class name)."""
    return {name: PpcaModel.fit(arrays, variance_share) for name, arrays in sorted(poses_by_class.items())}


def log_densities(models: dict[str, PpcaModel], poses: np.ndarray) -> np.ndarray:
    """(N, K) log densities of each pose under each model (in the models' order)."""
    return np.column_stack([model.log_density(poses) for model in models.values()])


def thesis_threshold(scores: list[np.ndarray], groups: list[str] | None = None) -> float:
    """The thesis's automatic threshold (section 4, tables 4.5 to 4.8).

    `scores` holds one (N_i, K) log-density array per test clip. The threshold t is
    set so that, averaged over the test groups, each pose lies above t for exactly one
    class: the K x G table of shares (percent of a group's poses above t under each
    class) sums to G x 100 % ("300 %" for the thesis's three classes). Groups are the
    test clips' true classes when known, else each clip is its own group; every group
    weighs the same, whatever its number of poses.
    """
    if groups is None:
        groups = [str(i) for i in range(len(scores))]
    frames: dict[str, int] = {}
    for s, g in zip(scores, groups):
        frames[g] = frames.get(g, 0) + len(s)
    values = np.concatenate([s.ravel() for s in scores])
    weights = np.concatenate([np.full(s.size, 1.0 / frames[g]) for s, g in zip(scores, groups)])
    target = float(len(frames))  # each group's poses match one class on average
    order = np.argsort(-values, kind="stable")
    values, cumulative = values[order], np.cumsum(weights[order])
    i = int(np.searchsorted(cumulative, target - 1e-9))
    if i >= len(values) - 1:
        return float(values[-1] - 1.0)
    return float(0.5 * (values[i] + values[i + 1]))  # strictly between the last counted and the first not


# --- classifying clips (`mcz classify`, benchmarks/classification.py) ---------------------------


def classification_poses(clip) -> np.ndarray:
    """A LoadedClip's poses as the classifier sees them.

    The aligned family (aligned, scaled, normalised) is used as the codec stores it: root
    translation and heading are already in the separate root track. `channels` drops the
    root's channels (translation and orientation; thesis: "only the root motion aligned
    version of the data formats were used") and orders the other bones by skeleton joint
    order, in degrees, so files with different bone orders or angle units compare.
    `positions` is kept as is (global positions: where a subject stands counts too).
    """
    if clip.representation_name != "channels":
        return clip.poses
    layout = clip.layout
    columns = layout.columns()
    order = [b for b in clip.model.names if b in columns and b != clip.model.names[0]]
    values = np.concatenate([clip.poses[:, columns[b]] for b in order], axis=1)
    return np.degrees(values) if layout.angle_unit == "rad" else values


def train_models(train: dict[str, str], poses: dict[str, np.ndarray],
                 variance_share: float = DEFAULT_VARIANCE_SHARE) -> dict[str, PpcaModel]:
    """One model per class: `train` maps clip path -> class, `poses` clip path -> (frames, M)."""
    by_class: dict[str, list[np.ndarray]] = {}
    for path, name in train.items():
        by_class.setdefault(name, []).append(poses[path])
    widths = {a.shape[1] for arrays in by_class.values() for a in arrays}
    if len(widths) > 1:
        raise ValueError(f"training clips have different pose widths {sorted(widths)}: use one skeleton layout")
    return fit_class_models(by_class, variance_share)


def classify(models: dict[str, PpcaModel], tests: dict[str, np.ndarray], truth: dict[str, str] | None = None,
             threshold: float | str = "auto") -> dict:
    """Score every test clip against every class model (the thesis experiment).

    Returns a JSON-able report: the threshold; per clip the share (%) of its poses whose
    log density is above the threshold for each class, the mean log density per class,
    the share of poses for which each class has the highest density ("pose_votes") and
    the class with the most votes ("best"); and, when `truth` gives the test clips'
    classes, the table in the thesis layout (rows: class models, columns: test classes,
    cells: % of that column's poses above the threshold, pooled over its clips) plus the
    share of poses and of clips whose best class is the true one.
    """
    truth = truth or {}
    names = list(models)
    scores = {path: log_densities(models, p) for path, p in tests.items()}
    labelled = [p for p in tests if p in truth]
    if threshold == "auto":
        groups = [truth[p] for p in tests] if len(labelled) == len(tests) and tests else None
        value = thesis_threshold(list(scores.values()), groups)
        rule = "auto: test poses match one class on average (thesis: the table sums to columns x 100 %)"
    else:
        value, rule = float(threshold), "given"
    clips = []
    for path, s in scores.items():
        above = (s > value).mean(axis=0) * 100.0
        mean_log = s.mean(axis=0)
        votes = np.bincount(s.argmax(axis=1), minlength=len(names)) / len(s) * 100.0
        clips.append({"path": path, "class": truth.get(path), "frames": int(len(s)),
                      "share": dict(zip(names, map(float, above))),
                      "mean_log_density": dict(zip(names, map(float, mean_log))),
                      "pose_votes": dict(zip(names, map(float, votes))),
                      "best": names[int(np.argmax(votes))]})
    report = {
        "threshold": value,
        "threshold_rule": rule,
        "classes": {n: {"components": m.q, "rho": m.rho, "dim": m.dim, "frames": m.count} for n, m in models.items()},
        "clips": clips,
    }
    if labelled:
        columns = sorted({truth[p] for p in labelled}, key=lambda c: (c not in names, names.index(c) if c in names else c))
        table, correct_poses, poses_total = [], 0, 0
        for row_name in names:
            k = names.index(row_name)
            row = []
            for col in columns:
                arrays = [scores[p][:, k] for p in labelled if truth[p] == col]
                row.append(float((np.concatenate(arrays) > value).mean() * 100.0))
            table.append(row)
        for p in labelled:
            if truth[p] in names:
                correct_poses += int((scores[p].argmax(axis=1) == names.index(truth[p])).sum())
                poses_total += len(scores[p])
        known = [c for c in clips if c["class"] in names]
        report["table"] = {"rows": names, "columns": columns, "share": table}
        report["diagonal_mean"] = float(np.mean([table[names.index(c)][j] for j, c in enumerate(columns) if c in names])) if known else None
        off = [table[i][j] for i in range(len(names)) for j, c in enumerate(columns) if c != names[i]]
        report["off_diagonal_mean"] = float(np.mean(off)) if off else None
        report["pose_accuracy"] = correct_poses / poses_total * 100.0 if poses_total else None
        report["clip_accuracy"] = (sum(c["best"] == c["class"] for c in known) / len(known) * 100.0) if known else None
    return report


def format_table(report: dict, title: str | None = None) -> str:
    """The confusion table in the thesis layout (tables 4.5 to 4.8), as plain text."""
    table = report["table"]
    head = [f"Test {c}" for c in table["columns"]]
    first = max([len(f"{r} class") for r in table["rows"]] + [len("class")])
    widths = [max(len(h), 7) for h in head]
    lines = []
    if title:
        lines.append(title)
    lines.append(f"{'':<{first}}  " + "  ".join(f"{h:>{w}}" for h, w in zip(head, widths)))
    for name, row in zip(table["rows"], table["share"]):
        lines.append(f"{name + ' class':<{first}}  " + "  ".join(f"{v:>{w}.2f}" for v, w in zip(row, widths)))
    return "\n".join(lines)
