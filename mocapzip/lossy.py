"""The lossy codec: one PCA basis per class, a temporal transform of the projected curves,
uniform dead-zone quantisation and context-modelled range coding (codec/coefficients.py),
with the error budget found by search.

Why one quantiser step for every coefficient of a clip: the PCA basis and the DCT are
orthonormal, so a coefficient error of size e costs the same squared pose error
wherever it sits; equal steps are the rate-distortion optimum (equal slopes) while
coefficients are dense. At 1 cm the non-zero high frequencies are isolated and cost more
bits than their error is worth, so each clip also gets a band (see `code_clip`). The
root track is scaled into the same units (cm) first, yaw by a typical joint radius,
because a yaw error moves a joint by (distance from root) x (angle). Its step is a fixed
share of the pose step (ROOT_STEP_RATIO): a root error moves every joint by its full size,
while a pose coefficient's error is spread over all joints, so equal slopes want the root
coded finer.
"""

from __future__ import annotations

import io
import math
import multiprocessing
import os
import struct
import threading
import time
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass
from functools import cached_property

import numpy as np

from .codec.coefficients import Priors, check_matrix_shape, decode_matrices, encode_matrices, matrix_shapes
from .codec.entropy import decode_ints, encode_ints, encode_sparse
from .codec.pca import CovarianceAccumulator, PcaBasis
from .codec.quantise import UniformQuantiser
from .formats.errors import MocapFormatError
from .limits import MAX_VALUES_PER_CLIP
from .search import largest_step, smallest_count

YAW_RADIUS_CM = 50.0  # a typical joint's distance from the root: yaw error x this = cm
MEAN_STEP_CM = 1e-3  # the class mean is kept finely: its error repeats on every frame
# root track step / pose step; `python benchmarks/root_step.py` (CMU subjects 02, 07, 13 and 35
# at 1 cm, B/frame, format 4): 1.0: 1.625, 0.5: 1.502, 0.25: 1.457, 0.2: 1.452, 0.1: 1.463
ROOT_STEP_RATIO = 0.2


@dataclass
class ClassBasis:
    """A class's mean pose and its first Q principal directions, as stored (quantised).

    Each direction j is stored on its own grid, steps[j]. A basis error d moves a pose by
    d times the coefficient, so directions with small coefficients (small variance) can be
    stored coarsely: `steps_for` makes that trade explicit.
    """

    mean: np.ndarray  # (M,)
    components: np.ndarray  # (M, Q)
    steps: np.ndarray  # (Q,) quantiser step of each stored direction

    @staticmethod
    def steps_for(variances: np.ndarray, error_cm: float, precision: float) -> np.ndarray:
        """Basis steps that add about `precision` x error_cm to a pose along each direction."""
        return precision * error_cm / np.sqrt(np.maximum(variances, (precision * error_cm) ** 2))

    @classmethod
    def quantised(cls, mean: np.ndarray, components: np.ndarray, steps: np.ndarray) -> "ClassBasis":
        """Round mean and components to what the archive stores, so encoding sees the decoder's basis."""
        return cls.decode(cls(mean, components, np.asarray(steps, np.float32)).encode())

    def encode(self, coder: str = "context") -> bytes:
        """`coder` as for `CodedClip.payload`. "context" and "primed" write one range-coded
        stream of three matrices: the mean's integers, each basis row's reference row and the
        basis integers less their reference row's (`_reference_rows`); bases are too few to
        train priors on. "zstd" (format 1) writes the mean and basis integers as two ints blobs."""
        steps = self.steps.astype("<f4")
        ints = np.round(self.components / steps.astype(np.float64)).astype(np.int64)
        mean_ints = np.round(self.mean / MEAN_STEP_CM).astype(np.int64)
        out = io.BytesIO()
        out.write(struct.pack("<II", self.mean.size, self.components.shape[1]))
        out.write(steps.tobytes())
        if coder != "zstd":
            references = _reference_rows(ints)
            rows = np.arange(len(ints))
            residuals = ints - np.where(references[:, None] >= 0, ints[references], 0)
            offsets = np.where(references >= 0, rows - references, 0)  # 0: no reference
            out.write(encode_matrices([mean_ints[:, None], offsets[:, None], residuals]))
        else:
            for blob in (encode_ints(mean_ints), encode_ints(ints)):
                out.write(struct.pack("<I", len(blob)))
                out.write(blob)
        return out.getvalue()

    @classmethod
    def decode(cls, blob: bytes, coder: str = "context") -> "ClassBasis":
        """Inverse of `encode`; the declared m x q is checked against the limits before anything is allocated."""
        m, q = _unpack("<II", blob, 0)
        check_matrix_shape(m, q)
        pos = 8
        steps = np.frombuffer(blob, "<f4", q, pos)
        pos += 4 * q
        if coder != "zstd":
            # Format 3 stores mean, reference offsets and residuals; format 2 mean and basis.
            # Checked on the header, before anything is decoded (a damaged shape must not allocate).
            stored = matrix_shapes(blob[pos:])
            expected = [(m, 1), (m, 1), (m, q)] if len(stored) == 3 else [(m, 1), (m, q)]
            if stored != expected:
                raise ValueError(f"class basis matrices of shapes {stored} for a {m} x {q} basis")
            parts = decode_matrices(blob[pos:], expected)
            if len(parts) == 3:
                parts = [parts[0], _undo_references(parts[2], parts[1].ravel())]
        else:
            parts = []
            for values in (m, m * q):
                (n,) = _unpack("<I", blob, pos)
                parts.append(decode_ints(blob[pos + 4 : pos + 4 + n], values))
                pos += 4 + n
            if pos != len(blob):
                raise ValueError("class basis has trailing bytes")
        mean = parts[0].reshape(m).astype(np.float64) * MEAN_STEP_CM
        components = parts[1].reshape(m, q).astype(np.float64) * steps.astype(np.float64)
        return cls(mean, components, steps.copy())

    @property
    def q(self) -> int:
        return self.components.shape[1]

    def project(self, poses: np.ndarray) -> np.ndarray:
        """Least-squares coefficients (the stored basis is only nearly orthonormal)."""
        return (poses - self.mean) @ self._projector

    @cached_property
    def _projector(self) -> np.ndarray:
        return np.linalg.pinv(self.components).T

    def reconstruct(self, coefficients: np.ndarray) -> np.ndarray:
        return self.mean + coefficients @ self.components.T


def _reference_rows(ints: np.ndarray) -> np.ndarray:
    """For each basis row, the earlier row it is best coded against (-1: none).

    Pose columns come in related groups: a child joint's position and axis move with its
    parent's, so their basis rows are alike, and the difference is smaller to code. Each
    row takes the earlier row that leaves the smallest sum of absolute differences, if
    that beats coding the row as it is.
    """
    references = np.full(len(ints), -1, np.int64)
    for row in range(1, len(ints)):
        costs = np.abs(ints[row] - ints[:row]).sum(axis=1)
        best = int(np.argmin(costs))
        if costs[best] < np.abs(ints[row]).sum():
            references[row] = best
    return references


def _undo_references(residuals: np.ndarray, offsets: np.ndarray) -> np.ndarray:
    """Basis integers from `_reference_rows` residuals and offsets (row - reference, 0: none)."""
    rows = np.arange(len(offsets))
    if np.any((offsets < 0) | (offsets > rows)):
        raise ValueError("class basis refers to a row that does not come before")
    ints = residuals.copy()
    for row in np.flatnonzero(offsets):
        ints[row] += ints[row - offsets[row]]
    return ints


def scale_root(root: np.ndarray) -> np.ndarray:
    """Root track (x, y, z cm, yaw rad) in cm-equivalent units."""
    return root * np.array([1.0, 1.0, 1.0, YAW_RADIUS_CM])


def unscale_root(scaled: np.ndarray) -> np.ndarray:
    return scaled / np.array([1.0, 1.0, 1.0, YAW_RADIUS_CM])


def dequantise_curves(ints: np.ndarray, step: float, transform, dead_zone: float, n_frames: int) -> np.ndarray:
    return transform.inverse(UniformQuantiser(step, dead_zone).dequantise(ints), n_frames)


@dataclass
class CodedClip:
    """A clip's quantised coefficients: what the archive stores for it.

    Three stream layouts, named by the archive's `coefficient_coder` setting:
    "primed" (coefficients.py: pose and root matrices in one range-coded stream whose models
    start from the archive's priors; format version 3), "context" (the same, models starting
    at 1/2; format 2) and "zstd" (entropy.py: each matrix in its own zstd frame; format 1).
    """

    pose_step: float
    pose_ints: np.ndarray  # (frames, Q) transform coefficients
    root_step: float
    root_ints: np.ndarray | None  # (frames, 4), or None for representations without a root track

    @property
    def matrices(self) -> list[np.ndarray]:
        return [self.pose_ints] if self.root_ints is None else [self.pose_ints, self.root_ints]

    def payload(self, coder: str = "context", priors: Priors | None = None) -> bytes:
        """`priors`: the archive's, for coder "primed"."""
        matrices, priors = self.matrices, _priors_for(coder, priors)
        if coder != "zstd":
            return struct.pack("<ff", self.pose_step, self.root_step) + encode_matrices(matrices, priors)
        parts = [encode_sparse(m) for m in matrices]
        head = struct.pack("<ddB", self.pose_step, self.root_step, len(parts))
        return head + b"".join(struct.pack("<I", len(p)) + p for p in parts)

    @classmethod
    def from_payload(cls, blob: bytes, coder: str = "context", shapes=None,
                     priors: Priors | None = None) -> "CodedClip":
        """`shapes`: the pose and root matrices' shapes when the caller knows them (checked first).

        The payload may come from anyone: its matrix count and shapes are checked (against
        `shapes` and the limits, `check_matrix_shape`) before anything is allocated for them.
        """
        priors = _priors_for(coder, priors)
        if coder != "zstd":
            pose_step, root_step = _unpack("<ff", blob, 0)
            count = len(matrix_shapes(blob[8:]))
        else:
            pose_step, root_step, count = _unpack("<ddB", blob, 0)
        if not 1 <= count <= 2:
            raise ValueError(f"clip payload holds {count} matrices")
        if coder != "zstd":
            arrays = decode_matrices(blob[8:], shapes, priors)
        else:
            pos, arrays = 17, []
            # format 1: each matrix at most the values its expected shape holds (unknown: an AMC clip's)
            most = [math.prod(shape) for shape in shapes] if shapes is not None else [MAX_VALUES_PER_CLIP] * count
            for k in range(count):
                (size,) = _unpack("<I", blob, pos)
                arrays.append(decode_ints(blob[pos + 4 : pos + 4 + size], most[k]))
                pos += 4 + size
                if arrays[-1].ndim != 2:
                    raise ValueError(f"clip payload holds a matrix of shape {arrays[-1].shape}")
                check_matrix_shape(*arrays[-1].shape)
            if pos != len(blob):
                raise ValueError("clip payload has trailing bytes")
            if shapes is not None and [a.shape for a in arrays] != [tuple(s) for s in shapes][:count]:
                raise ValueError(f"clip matrices of shapes {[a.shape for a in arrays]}, expected {list(shapes)}")
        return cls(pose_step, arrays[0], root_step, arrays[1] if len(arrays) > 1 else None)


def _unpack(layout: str, blob: bytes, offset: int) -> tuple:
    """struct.unpack_from that reports a stream cut short as ValueError, which callers catch."""
    try:
        return struct.unpack_from(layout, blob, offset)
    except struct.error:
        raise ValueError(f"stream cut short: {struct.calcsize(layout)} bytes needed at byte {offset}") from None


def interim_coder(coder: str) -> str:
    """How clip streams are held until all are coded: as written, except that "primed" and
    "auto" streams are held as "context" ones (priors are trained on every clip first)."""
    return "zstd" if coder == "zstd" else "context"


def _priors_for(coder: str, priors: Priors | None) -> Priors | None:
    """The priors a stream of `coder` is coded with (None but for "primed"); refuses unknown coders,
    which would otherwise be taken for the last layout tried ("auto" is for compress only)."""
    if coder not in ("primed", "context", "zstd"):
        raise ValueError(f"unknown coefficient coder {coder!r}")
    if coder == "primed" and priors is None:
        raise ValueError("coefficient coder 'primed' needs the archive's priors")
    return priors if coder == "primed" else None


SEARCH_STRIDE = 8  # searches score every 8th frame (15 Hz at 120 Hz), denser below 2,048 frames; the final check all
PCA_SHARES = (0.3, 0.5, 0.7)  # candidate shares of the budget for PCA; the rest goes to quantisation
STEP_RANGE = (1e-4, 1e3)  # quantiser steps searched, in cm-equivalent units
BANDS = (1.0, 0.2, 0.16, 0.13, 0.11, 0.095, 0.08, 0.07, 0.06, 0.05, 0.043, 0.036, 0.03, 0.025, 0.02)  # kept shares
STEP_GUESS = 3.0  # typical step / target (CMU, 1 cm): where the step search starts
MAX_TRUNCATION_SHARE = 0.85  # a band whose truncation alone costs more of the budget is not tried
BASIS_REFINEMENTS = 4  # times the basis grid is refined when a clip cannot meet the target

class TargetError(MocapFormatError):
    """No coding of a clip meets the error target: the target is below the input's own precision."""


_SHARED: dict = {}  # what forked workers read (clips are large: they are inherited, not pickled)


def encode_class(clips, transform, settings, jobs: int = 1, accumulator: CovarianceAccumulator | None = None):
    """Fit the class basis and code each clip within settings.error_cm; return (basis, payloads, errors,
    twists): each clip's stream (`CodedClip.payload`), achieved (mean, max) error and twist flips
    (`LoadedClip.final_check`, for its row).

    The budget split is a search: for each candidate PCA share, the class keeps the fewest
    components that bring every clip's PCA-only error under that share, then each clip gets
    the largest quantiser step that keeps its end-to-end error under the whole budget. The
    split with the fewest bytes wins. `settings.split` forces one split instead.

    `clips` may load each clip when indexed (`clip.ClipsOnDemand`): a class need not fit in
    memory. Each clip is indexed once for the component search and once to be coded with every
    candidate basis (again only if a basis must be stored finer); `accumulator`, the class's
    weighted poses when the caller has already summed them, saves one more pass.
    """
    if accumulator is None:
        accumulator = CovarianceAccumulator(clips[0].poses.shape[1])
        for clip in clips:
            accumulator.add(clip.poses)
    pca = PcaBasis.fit(accumulator)
    target = settings.error_cm
    shares = [settings.split[1] / sum(settings.split)] if settings.split else PCA_SHARES
    _SHARED.update(clips=clips, pca=pca, transform=transform, settings=settings)
    try:
        needed = np.array(_parallel(_components_for_shares, range(len(clips)), jobs))  # (clips, shares)
        # Shares that need the same component count get the same basis and coding: code it once.
        counts = list(dict.fromkeys(int(needed[:, k].max()) for k in range(len(shares))))
        precision = dict.fromkeys(counts, settings.basis_precision)
        codings = {}  # component count -> (basis, payloads, errors, twists)
        pending = counts
        for _ in range(BASIS_REFINEMENTS):
            steps = [ClassBasis.steps_for(pca.variances[:q], target, precision[q]) for q in pending]
            bases = _SHARED["bases"] = [ClassBasis.quantised(pca.mean, pca.components[:, :q], step)
                                        for q, step in zip(pending, steps)]
            per_clip = _parallel(_code_clip, range(len(clips)), jobs)  # per clip, (payload, error, twists) per basis
            for b, (q, basis) in enumerate(zip(pending, bases)):
                payloads, errors, twists = zip(*(codings_of_clip[b] for codings_of_clip in per_clip))
                codings[q] = (basis, list(payloads), list(errors), list(twists))
            pending = [q for q in pending if max(e[0] for e in codings[q][2]) > target]
            if not pending:
                break
            for q in pending:
                precision[q] /= 4  # the rounded basis alone costs too much error: store it finer
        else:
            worst, index = max((e[0], i) for q in pending for i, e in enumerate(codings[q][2]))
            raise TargetError(f"no coding met {target:g} cm (this clip reached {worst:.4f} cm): the target is "
                              "finer than the precision of the clip's numbers allows; use a larger -e, or --lossless",
                              clips[index].source.amc)
    finally:
        _SHARED.clear()
    best = None
    for q in counts:  # in share order: on equal sizes the first share wins
        size = len(codings[q][0].encode(settings.coefficient_coder)) + sum(map(len, codings[q][1]))
        if best is None or size < best[0]:
            best = (size, codings[q])
    return best[1]


def _parallel(function, items, jobs: int) -> list:
    """map over items, in `jobs` forked processes when that can help."""
    items = list(items)
    if jobs <= 1 or len(items) < 2 or "fork" not in multiprocessing.get_all_start_methods():
        return [function(i) for i in items]
    with ProcessPoolExecutor(min(jobs, len(items)), mp_context=multiprocessing.get_context("fork"),
                             initializer=_exit_with_parent, initargs=(os.getpid(),)) as pool:
        return list(pool.map(function, items))


def _exit_with_parent(parent: int) -> None:
    """Worker start-up: a watcher thread ends the worker once its parent is gone. A parent
    killed by SIGKILL runs no clean-up, and its workers would otherwise wait for work forever."""

    def watch() -> None:
        while os.getppid() == parent:
            time.sleep(0.5)
        os._exit(1)

    threading.Thread(target=watch, name="exit-with-parent", daemon=True).start()


def _components_for_shares(index: int) -> list[int]:
    """For each PCA share, the fewest components that keep this clip's PCA-only error within it."""
    clip, pca, settings = _SHARED["clips"][index], _SHARED["pca"], _SHARED["settings"]
    frames = slice(None, None, SEARCH_STRIDE)
    coef = (clip.poses[frames] - pca.mean) @ pca.components
    root = None if clip.root is None else clip.root[frames]
    cache: dict[int, float] = {}

    def error(q: int) -> float:
        if q not in cache:
            approx = pca.mean + coef[:, :q] @ pca.components[:, :q].T
            cache[q] = clip.error(approx, root, frames)[0]
        return cache[q]

    shares = [settings.split[1] / sum(settings.split)] if settings.split else PCA_SHARES
    return [smallest_count(error, share * settings.error_cm, 0, pca.components.shape[1]) for share in shares]


def _code_clip(index: int) -> list[tuple[bytes, tuple[float, float], dict]]:
    """The clip coded with each candidate basis, as (payload, (mean, max) error, twist flips):
    one load for all."""
    settings, clip, transform = _SHARED["settings"], _SHARED["clips"][index], _SHARED["transform"]
    out = []
    for basis in _SHARED["bases"]:
        coded, error, twists = code_clip(clip, basis, transform, settings.error_cm, settings.dead_zone,
                                         settings.split)
        out.append((coded.payload(interim_coder(settings.coefficient_coder)), error, twists))
    return out


def code_clip(clip, basis: ClassBasis, transform, target: float, dz: float, split=None):
    """The smallest coding of this clip within `target`, verified on every frame.

    Two knobs are searched: the quantiser step, and the band, the share of the temporal
    coefficients (lowest frequencies first) the clip keeps at all. Dropping the top of the
    band costs some error, paid for by a finer step, but high-frequency coefficients are
    isolated and expensive to code, so a narrower band is often smaller overall. For each
    band (widest first) the largest step within `target` is found and the coded size
    measured; the search stops when a band cannot meet the target or sizes stop falling.

    Returns the coded clip, its achieved (mean, max) error and its twist flips (for its row,
    `LoadedClip.final_check`). `split` (R, P, T shares)
    forces the root track's share of the budget and keeps the whole band (the thesis's
    experiments); otherwise the root step is ROOT_STEP_RATIO of the pose step.
    """
    n = clip.motion.n_frames
    pose_coef = transform.forward(basis.project(clip.poses))
    root_coef = None if clip.root is None else transform.forward(scale_root(clip.root))
    sample = slice(None, None, max(1, min(SEARCH_STRIDE, n // 256)))  # short clips: every frame

    def code(pose_step: float, root_step: float, band: float = 1.0) -> CodedClip:
        pose_step, root_step = float(np.float32(pose_step)), float(np.float32(root_step))  # as stored
        pose_ints = UniformQuantiser(pose_step, dz).quantise(pose_coef)
        root_ints = None if root_coef is None else UniformQuantiser(root_step, dz).quantise(root_coef)
        kept = math.ceil(band * n)
        pose_ints[kept:] = 0
        if root_ints is not None:
            root_ints[kept:] = 0
        return CodedClip(pose_step, pose_ints, root_step, root_ints)

    def error(pose_step: float, root_step: float, band: float = 1.0, exact: str | None = None) -> float:
        poses, root = reconstruct(code(pose_step, root_step, band), basis, transform, dz, n, sample)
        if exact == "poses":
            poses = clip.poses[sample]
        elif exact == "root":
            root = clip.root[sample]
        return clip.error(poses, root, sample)[0]

    if split and root_coef is not None:
        r_share = split[0] / sum(split)
        root_step, _ = largest_step(lambda s: error(1.0, s, exact="poses"), r_share * target, *STEP_RANGE)
        pose_step, _ = largest_step(lambda s: error(s, 1.0, exact="root"), (1 - r_share) * target, *STEP_RANGE)
        band = 1.0
    else:  # the root step follows the pose step
        pose_step, band = _smallest_over_bands(lambda step, band: code(step, step * ROOT_STEP_RATIO, band),
                                               lambda step, band: error(step, step * ROOT_STEP_RATIO, band), target)
        root_step = pose_step * ROOT_STEP_RATIO
    coded = code(pose_step, root_step, band)
    achieved, twists = clip.final_check(*reconstruct(coded, basis, transform, dz, n))
    while achieved[0] > target and coded.pose_step > STEP_RANGE[0]:  # the sampled search missed: tighten
        coded = code(coded.pose_step * 0.9, coded.root_step * 0.9, band)
        achieved, twists = clip.final_check(*reconstruct(coded, basis, transform, dz, n))
    return coded, achieved, twists


def _smallest_over_bands(code, error, target: float) -> tuple[float, float]:
    """(step, band) of the smallest coding within `target` on the sampled frames (see code_clip);
    `code` and `error` take (step, band).

    The error of dropping a band's top alone (finest step) is cheap to score, so bands whose
    truncation takes more than MAX_TRUNCATION_SHARE of the budget are never step-searched.
    Sizes fall as the band narrows until the step must shrink fast, so the search starts at
    the narrowest admissible band and widens while the size keeps falling.
    """
    finest = STEP_RANGE[0]

    def admissible(i: int) -> bool:
        return error(finest, BANDS[i]) <= MAX_TRUNCATION_SHARE * target

    # BANDS narrow as i grows and the truncation error grows with them; BANDS[0] keeps everything
    widest, narrowest = 0, len(BANDS) - 1
    if not admissible(narrowest):
        while narrowest - widest > 1:
            middle = (widest + narrowest) // 2
            widest, narrowest = (middle, narrowest) if admissible(middle) else (widest, middle)
        narrowest = widest
    best, best_size = None, None
    low, high, guess = *STEP_RANGE, STEP_GUESS * target
    for band in BANDS[narrowest::-1]:
        step, err = largest_step(lambda s: error(s, band), target, low, high, guess=guess)
        if err > target:
            break
        size = len(code(step, band).payload())
        if best is not None and size >= best_size:
            break
        best, best_size = (step, band), size
        low, high, guess = step, step * 8, step * 1.25  # a wider band allows a coarser step
    return best if best is not None else (finest, 1.0)


def reconstruct(coded: CodedClip, basis: ClassBasis, transform, dead_zone: float, n_frames: int,
                frames=slice(None)):
    """Poses and root track (unscaled) of `frames` from a clip's quantised coefficients."""
    coef = dequantise_curves(coded.pose_ints, coded.pose_step, transform, dead_zone, n_frames)[frames]
    poses = basis.reconstruct(coef)
    root = None
    if coded.root_ints is not None:
        root = unscale_root(dequantise_curves(coded.root_ints, coded.root_step, transform, dead_zone, n_frames)[frames])
    return poses, root
