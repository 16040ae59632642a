"""Rate control of the lossy codec: per class a PCA basis, per clip a temporal band and the
largest quantiser step whose decode, scored end to end (`inputs.clip.LoadedClip.error`),
stays within the error target. The stages it drives live in `mocapzip.codec`.

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

import math
import multiprocessing
import os
import threading
import time
from concurrent.futures import ProcessPoolExecutor

import numpy as np

from mocapzip.codec.basis import ClassBasis
from mocapzip.codec.clip_stream import CodedClip, reconstruct, scale_root
from mocapzip.codec.pca import CovarianceAccumulator, PcaBasis
from mocapzip.codec.quantise import UniformQuantiser
from mocapzip.formats.errors import MocapFormatError
from mocapzip.ratecontrol.search import largest_step, smallest_count

ROOT_STEP_RATIO = 0.2


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
        size = len(codings[q][0].encode()) + sum(map(len, codings[q][1]))
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
        out.append((coded.payload(), error, twists))
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
