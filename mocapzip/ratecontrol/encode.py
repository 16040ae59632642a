"""Rate control of the lossy codec: per class a PCA basis, per clip a temporal band and the
largest quantiser step whose decode, scored end to end (`inputs.clip.LoadedClip.error`),
stays within the error target. The searches run on cheap proxies of that error
(`ratecontrol.proxy`), which a few end-to-end scores calibrate. The stages it drives live in
`mocapzip.codec`.

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
from dataclasses import dataclass
from functools import cached_property

import numpy as np

from mocapzip.codec.basis import ClassBasis
from mocapzip.codec.clip_stream import CodedClip, reconstruct, scale_root
from mocapzip.codec.foot_lock import Stances
from mocapzip.codec.patches import FramePatches
from mocapzip.codec.pca import CovarianceAccumulator, PcaBasis
from mocapzip.codec.quantise import UniformQuantiser
from mocapzip.inputs.clip import FinalCheck
from mocapzip.parallel import parallel_map, worker_state
from mocapzip.ratecontrol.max_error import Achieved, TargetError, achieved, smallest_within
from mocapzip.ratecontrol.planted_feet import planted
from mocapzip.ratecontrol.proxy import CodingProxy, TruncationProxy
from mocapzip.ratecontrol.search import largest_step, smallest_count_guided
from mocapzip.ratecontrol.target import CodingTarget

ROOT_STEP_RATIO = 0.2


SEARCH_STRIDE = 8  # searches score every 8th frame (15 Hz at 120 Hz), denser below 2,048 frames; the final check all
ESTIMATE_FRAMES = 64  # the estimates that choose a basis's precision sample every 8th frame down to 512 frames, 64 below
PCA_SHARE = 0.4  # of the error budget, for PCA truncation; the rest goes to the quantiser. The best single
# share on the shared CMU set (0.3 to 0.5 tried, at 1 and 0.5 cm); choosing among 0.3, 0.5 and 0.7 per class
# by estimated bytes, as before, came out 0.2 % larger at 1 cm, 0.7 % smaller at 0.5 cm, and took 25 % longer
STEP_RANGE = (1e-4, 1e3)  # quantiser steps searched, in cm-equivalent units
BANDS = (1.0, 0.2, 0.16, 0.13, 0.11, 0.095, 0.08, 0.07, 0.06, 0.05, 0.043, 0.036, 0.03, 0.025, 0.02)  # kept shares
STEP_GUESS = 3.0  # typical step / target (CMU, 1 cm): where the step search starts
MAX_TRUNCATION_SHARE = 0.85  # a band whose truncation alone costs more of the budget is not tried
BASIS_REFINEMENTS = 4  # times the basis grid is refined when a clip cannot meet the target
CALIBRATION_AIM = 0.995  # the proxy searches aim this far under the target ...
CALIBRATED_LOW = 0.985  # ... and a true error within [CALIBRATED_LOW, 1] x target is taken
MAX_CALIBRATIONS = 6  # end-to-end scores per clip before the step is tightened instead
STEP_TOLERANCE = 0.003  # proxy searches find the step to 0.3 % (1 % made the archive 0.6 % larger)
PROXY_CLOSE = 0.01  # ... or stop at a step whose proxy error is within 1 % under the aim: the proxy
# wobbles by about that much between steps 0.3 % apart (CMU: +0.04 % bytes, a third fewer proxy scores)
BAND_RESCALE = 0.03  # a proxy factor this far from the one the band was chosen with: choose it again
NARROWER_TRIAL = 1.02  # a narrower band whose proxy coding is at most this much larger is tried on true scores
# (1.06 tried more bands: on the shared CMU set 0.3 % smaller at 1 cm, 0.2 % at 0.5 cm, for 6 % more time)
COARSER_BASIS_SHARE = 0.25  # a chosen basis over this share of its class's estimated bytes is also tried coarser ...
COARSER_BASES = (2, 4)  # ... at these multiples of target.basis_precision
BRACKET = 0.01  # steps 1 % apart, one meeting the target and one not: the search is done
TOLERANCE_EXPONENT = 0.0  # seed 003's tolerances weighted by singular value (`component_weights`); 0: every
# component quantised alike. On the shared CMU set at 1 cm, 0.25 is 7.9 % larger, -0.25 0.7 % (benchmarks/seed_poly.py)


def component_weights(variances: np.ndarray) -> np.ndarray:
    """w_j = (sigma_j / sigma_1) ** TOLERANCE_EXPONENT per component j. Its basis direction is
    stored 1 / w_j long, so its coefficients are w_j times what they were and one quantiser step
    on them is 1 / w_j steps on the component: for a positive exponent, the 2003 page's looser
    fits of the components of small singular values, with nothing new for a decoder to read."""
    if TOLERANCE_EXPONENT == 0 or not len(variances):
        return np.ones(len(variances))
    return (np.maximum(variances, 1e-30) / max(variances[0], 1e-30)) ** (TOLERANCE_EXPONENT / 2)


# what the workers of a class's maps read (its clips by index: each loads them, never pickled)
_SHARED = worker_state(__name__)


def encode_class(clips, transform, target: CodingTarget, jobs: int = 1,
                 accumulator: CovarianceAccumulator | None = None):
    """Fit the class basis and code each clip within target.error_cm; return (basis, codings): per
    clip a `ClassCoding` (its stream, achieved errors, twist flips and, with a bound on single
    joints, frame patches).

    The budget is split between the basis and the quantiser: the class keeps the fewest
    components that bring every clip's PCA-only error under PCA_SHARE of it (target.split
    forces another share). Each clip's bytes with that basis are then estimated at the largest
    step its calibrated proxy allows (`_estimated_sizes`), which is also where its coding starts
    (`code_clip`).

    A basis is stored at `target.basis_precision`. One that would take more than
    COARSER_BASIS_SHARE of its class's estimated bytes (a class of few or short clips) is also
    estimated at COARSER_BASES times coarser, and the smallest estimate is coded.

    `clips` may load each clip when indexed (`clip.ClipsOnDemand`): a class need not fit in
    memory. Each clip is indexed once for the component search, once or twice for the
    estimates and once to be coded (again only if the basis must be stored finer); `accumulator`, the
    class's weighted poses when the caller has already summed them, saves one more pass.
    """
    if accumulator is None:
        accumulator = CovarianceAccumulator(clips[0].poses.shape[1])
        for clip in clips:
            accumulator.add(clip.poses)
    pca = PcaBasis.fit(accumulator)
    _SHARED.update(clips=clips, pca=pca, transform=transform, target=target)

    def basis_of(q: int, precision: float) -> ClassBasis:
        weights = component_weights(pca.variances[:q])
        return ClassBasis.quantised(pca.mean, pca.components[:, :q] / weights,
                                    ClassBasis.steps_for(pca.variances[:q], target.error_cm, precision) / weights)

    try:
        precision = target.basis_precision
        basis = basis_of(max(parallel_map(_components_for_share, range(len(clips)), jobs)), precision)
        _SHARED["starts"] = [None] * len(clips)
        if not target.split:  # a forced split codes on end-to-end scores alone: nothing to estimate
            (total,), (_SHARED["starts"],) = _estimated([basis], jobs)
            if len(basis.encode()) > COARSER_BASIS_SHARE * total:
                # a basis that is much of its class's bytes (few or short clips) may pay to be stored coarser
                trials = [(precision * m, basis_of(basis.q, precision * m)) for m in COARSER_BASES]
                totals, starts = _estimated([b for _, b in trials], jobs)
                for (coarser, trial), trial_total, trial_starts in zip(trials, totals, starts):
                    if trial_total < total:
                        precision, basis, total, _SHARED["starts"] = coarser, trial, trial_total, trial_starts
        basis, codings = _coded_with(basis, precision, basis_of, clips, target.error_cm, jobs)
    finally:
        _SHARED.clear()
    return basis, codings


def _coded_with(basis: ClassBasis, precision: float, basis_of, clips, target: float, jobs: int):
    """(basis, per clip its `ClassCoding`): every clip coded with `basis` (stored at `precision`),
    stored finer (`basis_of(q, precision)`) while some clip cannot meet the target because of its rounding."""
    for _ in range(BASIS_REFINEMENTS):
        _SHARED["basis"] = basis
        codings = parallel_map(_code_clip, range(len(clips)), jobs)
        worst, index = max((coding.achieved.mean, i) for i, coding in enumerate(codings))
        if worst <= target:
            return basis, codings
        precision /= 4  # the rounded basis alone costs too much error: store it finer
        basis = basis_of(basis.q, precision)
    raise TargetError(f"no coding met {target:g} cm (this clip reached {worst:.4f} cm): the target is "
                      "finer than the precision of the clip's numbers allows; use a larger -e, or --lossless",
                      clips[index].source.motion)


def _estimated(bases: list[ClassBasis], jobs: int) -> tuple[list[int], list[list]]:
    """Per basis, the class's estimated bytes (the basis and every clip, `_estimated_sizes`) and
    each clip's start for `code_clip`."""
    _SHARED["bases"] = bases
    estimates = parallel_map(_estimated_sizes, range(len(_SHARED["clips"])), jobs)  # per clip and basis: (bytes, start)
    totals = [len(b.encode()) + sum(clip[i][0] for clip in estimates) for i, b in enumerate(bases)]
    return totals, [[clip[i][1] for clip in estimates] for i in range(len(bases))]


def _components_for_share(index: int) -> int:
    """The fewest components that keep this clip's PCA-only error within `pca_share` of the
    target (scored end to end on every SEARCH_STRIDE-th frame), found by true scores guided by
    `proxy.TruncationProxy` (`search.smallest_count_guided`)."""
    clip, pca, target = _SHARED["clips"][index], _SHARED["pca"], _SHARED["target"]
    frames = slice(None, None, SEARCH_STRIDE)
    poses, root = clip.poses[frames], None if clip.root is None else clip.root[frames]
    proxy = TruncationProxy(poses, pca.mean, pca.components, clip.representation.joint_position_columns(clip.model))

    def error(q: int) -> float:
        return clip.error(proxy.truncated(q), root, frames)[0]

    allowed = pca_share(target) * target.error_cm
    return smallest_count_guided(error, proxy, allowed, 0, pca.components.shape[1])


def pca_share(target: CodingTarget) -> float:
    """The share of the error budget PCA truncation may take (the rest is the quantiser's)."""
    return target.split[1] / sum(target.split) if target.split else PCA_SHARE


def _estimated_sizes(index: int) -> list[tuple[int, tuple[float, float, float]]]:
    """Per basis in `_SHARED["bases"]` (the class basis, or copies of it stored coarser), the
    clip's coded bytes as the calibrated proxy predicts them, and where its coding with that
    basis starts (step, band, proxy factor: `code_clip`'s `start`).

    Each basis's bands are searched near the band the one before picked (`_ClipSearch.pick`);
    one end-to-end score per basis sets its factor: the proxy misses part of the error the
    basis's rounding leaves, so the factor differs between bases."""
    target, clip, transform = _SHARED["target"], _SHARED["clips"][index], _SHARED["transform"]
    estimates, scale, step, band = [], 1.0, None, None
    for basis in _SHARED["bases"]:
        search = _ClipSearch(clip, basis, transform, target.error_cm, target.dead_zone, ESTIMATE_FRAMES)
        step, band = search.pick(scale, near=band, guess=step)
        scale = search.measured_scale(step, band, scale)
        step = search.step_for(band, scale, guess=step)
        estimates.append((len(search.code(step, band).payload()), (step, band, scale)))
    return estimates


@dataclass
class ClassCoding:
    """A clip's coding as its class stores it: the stream, its row's errors and twist flips, and its patches."""

    payload: bytes  # `CodedClip.payload`, "context" coder
    achieved: Achieved  # every joint of every frame as written, foot lock and patches applied
    patches: FramePatches | None  # `max_error.achieved`: None without a bound, or with no frame beyond it
    twists: dict  # twist flips for the clip's row (`LoadedClip.final_check`)
    stances: Stances | None = None  # --plant-feet: the stances its foot lock holds (`planted_feet.planted`)

    @cached_property
    def patch_bytes(self) -> int:
        return 0 if self.patches is None else len(self.patches.payload())

    @cached_property
    def stance_bytes(self) -> int:
        return 0 if self.stances is None else len(self.stances.payload())

    @property
    def size(self) -> int:
        return len(self.payload) + self.patch_bytes + self.stance_bytes


def _code_clip(index: int) -> ClassCoding:
    """The clip coded with the class basis (`coded_within`), from its estimate's start if any."""
    return coded_within(_SHARED["clips"][index], _SHARED["basis"], _SHARED["transform"], _SHARED["target"],
                        _SHARED["starts"][index])


def coded_within(clip, basis: ClassBasis, transform, target: CodingTarget,
                 start: tuple[float, float, float] | None = None) -> ClassCoding:
    """The clip coded with `basis`, its foot lock (target.plant_feet), and what it achieves; with a
    bound on single joints (target.bounds), at the mean aim that needs the fewest bytes with its
    patches (`max_error.smallest_within`). `start`: (step, band, proxy factor) of an estimate.
    Its achieved mean may exceed the target where the basis cannot meet it (the caller checks)."""
    step, band, scale = start or (None, None, None)

    def coded_at(aim: float) -> ClassCoding:
        start = (step, band) if aim == target.error_cm and step is not None else None  # what was estimated
        coding = code_clip(clip, basis, transform, aim, target.dead_zone, target.split, start, scale)
        check, stances = planted(clip, coding.check, target.error_cm) if target.plant_feet else (coding.check, None)
        return ClassCoding(coding.coded.payload(), *achieved(clip, check, target.bounds), coding.twists, stances)

    return smallest_within(coded_at, target.error_cm, target.bounds.on_joints)


@dataclass
class ClipCoding:
    """What `code_clip` chose, and what it measured on the way."""

    coded: CodedClip
    check: FinalCheck  # its decode, scored on every frame as written
    proxy_scale: float | None  # true error / proxy error last measured (None: not measured)
    checks: int  # end-to-end scores run (sampled or whole)

    @property
    def error(self) -> tuple[float, float]:
        """Achieved (mean, max) joint error, cm, every frame as written."""
        return self.check.error

    @property
    def twists(self) -> dict:
        """Twist flips for the clip's row (`LoadedClip.final_check`)."""
        return self.check.twists

    @cached_property
    def size(self) -> int:
        """Bytes of its stream (the "context" coder, as the searches measure), coded once."""
        return len(self.coded.payload())


def code_clip(clip, basis: ClassBasis, transform, target: float, dz: float, split=None,
              start: tuple[float, float] | None = None, proxy_scale: float | None = None) -> ClipCoding:
    """The smallest coding of this clip within `target`, verified on every frame.

    Two knobs are searched: the quantiser step, and the band, the share of the temporal
    coefficients (lowest frequencies first) the clip keeps at all. Dropping the top of the
    band costs some error, paid for by a finer step, but high-frequency coefficients are
    isolated and expensive to code, so a narrower band is often smaller overall.

    The searches run on `proxy.CodingProxy` times a factor, the ratio of true to proxy error
    last measured (`proxy_scale`, e.g. by the estimate that chose this basis; 1 at first), and
    true end-to-end scores only calibrate and verify (`_ClipSearch`): a few per clip instead of
    one per step tried. `start` (step, band), the estimate's for this target
    (`_estimated_sizes`), replaces the first band search. The coding returned has been checked
    on every frame as written (`LoadedClip.final_check`).

    `split` (R, P, T shares) forces the root track's share of the budget and keeps the whole
    band (the thesis's experiments; searched on end-to-end scores); otherwise the root step is
    ROOT_STEP_RATIO of the pose step.
    """
    search = _ClipSearch(clip, basis, transform, target, dz)
    if split and search.root_coef is not None:
        return search.split(split)
    return search.smallest(proxy_scale or 1.0, start)


class _ClipSearch:
    """One clip against one basis: its coefficients, codings of them, and their scores."""

    def __init__(self, clip, basis: ClassBasis, transform, target: float, dz: float, sampled_frames: int = 256):
        self.clip, self.basis, self.transform, self.target, self.dz = clip, basis, transform, target, dz
        self.n = clip.motion.n_frames
        self.projected = basis.project(clip.poses)
        self.pose_coef = transform.forward(self.projected)
        self.root_coef = None if clip.root is None else transform.forward(scale_root(clip.root))
        # every SEARCH_STRIDE-th frame, denser in short clips to keep `sampled_frames` (under that: every frame)
        self.sample = slice(None, None, max(1, min(SEARCH_STRIDE, self.n // sampled_frames)))
        self.checks = 0

    def code(self, step: float, band: float = 1.0, root_step: float | None = None) -> CodedClip:
        """The coefficients quantised with `step` (the root track's with `root_step`, by default
        ROOT_STEP_RATIO of it), rows past the band zeroed."""
        root_step = step * ROOT_STEP_RATIO if root_step is None else root_step
        pose_step, root_step = float(np.float32(step)), float(np.float32(root_step))  # as stored
        pose_ints = UniformQuantiser(pose_step, self.dz).quantise(self.pose_coef)
        root_ints = None if self.root_coef is None else UniformQuantiser(root_step, self.dz).quantise(self.root_coef)
        kept = math.ceil(band * self.n)
        pose_ints[kept:] = 0
        if root_ints is not None:
            root_ints[kept:] = 0
        return CodedClip(pose_step, pose_ints, root_step, root_ints)

    def sampled_error(self, coded: CodedClip, exact: str | None = None) -> float:
        """End-to-end mean error on the sampled frames; `exact` keeps "poses" or "root" original."""
        self.checks += 1
        poses, root = reconstruct(coded, self.basis, self.transform, self.dz, self.n, self.sample)
        if exact == "poses":
            poses = self.clip.poses[self.sample]
        elif exact == "root":
            root = self.clip.root[self.sample]
        return self.clip.error(poses, root, self.sample)[0]

    def final(self, coded: CodedClip, scale: float | None = None) -> ClipCoding:
        """`coded` scored on every frame as written."""
        self.checks += 1
        check = self.clip.final_check(*reconstruct(coded, self.basis, self.transform, self.dz, self.n))
        return ClipCoding(coded, check, scale, self.checks)

    def tightened(self, coding: ClipCoding, band: float) -> ClipCoding:
        """Finer codings (steps 10 % smaller each time) until one meets the target on every frame or
        the finest step is reached: the last resort when the searches missed."""
        while coding.error[0] > self.target and coding.coded.pose_step > STEP_RANGE[0]:
            coding = self.final(self.code(coding.coded.pose_step * 0.9, band, coding.coded.root_step * 0.9),
                                coding.proxy_scale)
        return coding

    def split(self, split) -> ClipCoding:
        """Root and pose steps searched apart on end-to-end scores, the root's within its share."""
        r_share = split[0] / sum(split)
        root_step, _ = largest_step(lambda s: self.sampled_error(self.code(1.0, root_step=s), exact="poses"),
                                    r_share * self.target, *STEP_RANGE)
        pose_step, _ = largest_step(lambda s: self.sampled_error(self.code(s, root_step=1.0), exact="root"),
                                    (1 - r_share) * self.target, *STEP_RANGE)
        return self.tightened(self.final(self.code(pose_step, root_step=root_step)), 1.0)

    @cached_property
    def proxy(self) -> CodingProxy:
        clip = self.clip
        columns = clip.representation.joint_position_columns(clip.model)
        character = None if clip.root is None else (clip.own_poses[:, columns].reshape(self.n, -1, 3), clip.root[:, 3])
        return CodingProxy(self.pose_coef, self.root_coef, self.basis.components, columns,
                           clip.poses - self.basis.reconstruct(self.projected), self.transform, self.dz, character,
                           self.sample)

    def predicted(self, step: float, band: float, scale: float) -> float:
        return scale * self.proxy(step, step * ROOT_STEP_RATIO, band)

    def step_for(self, band: float, scale: float, guess: float | None = None) -> float:
        """The largest step whose predicted error meets the aim, at `band`."""
        step, _ = largest_step(lambda s: self.predicted(s, band, scale), CALIBRATION_AIM * self.target, *STEP_RANGE,
                               rel_tol=STEP_TOLERANCE, guess=guess, close=PROXY_CLOSE)
        return step

    def pick(self, scale: float, near: float | None = None, guess: float | None = None) -> tuple[float, float]:
        """(step, band) of the smallest coding whose predicted error meets the aim; only bands next
        to `near` (the band another basis picked for the clip, at step `guess`) if given."""
        def error(step: float, band: float) -> float:
            return self.predicted(step, band, scale)

        target = CALIBRATION_AIM * self.target
        if near is None:
            return _smallest_over_bands(self.code, error, target)
        return _smallest_near_band(self.code, error, target, BANDS.index(near), guess)

    def measured_scale(self, step: float, band: float, scale: float) -> float:
        """The proxy factor measured by one end-to-end score (sampled) of the coding at `step`, `band`."""
        coded = self.code(step, band)
        measured, predicted = self.sampled_error(coded), self.proxy(coded.pose_step, coded.root_step, band)
        return measured / predicted if measured > 0 and predicted > 0 else scale

    def smallest(self, scale: float, start: tuple[float, float] | None = None) -> ClipCoding:
        """The band and step by the proxy (or `start`), then calibrated (`calibrate`). The proxy's
        error differs a little between bands, so the band is chosen again if the factor moved, and
        narrower bands (which the proxy slightly overstates) are tried on true scores while they
        come out smaller."""
        step, band = start or self.pick(scale)
        best = self.calibrate(step, band, scale)
        if abs(best.proxy_scale / scale - 1) > BAND_RESCALE:
            step, other = self.pick(best.proxy_scale)
            if other != band:
                candidate = self.calibrate(step, other, best.proxy_scale)
                if self._smaller(best, candidate) is candidate:
                    best, band = candidate, other
        index = BANDS.index(band)
        while index + 1 < len(BANDS) and best.error[0] <= self.target:
            narrower, scale = BANDS[index + 1], best.proxy_scale
            if not _admissible(lambda step, band: self.predicted(step, band, scale), self.target, narrower):
                break
            step = self.step_for(narrower, scale)
            if len(self.code(step, narrower).payload()) > NARROWER_TRIAL * best.size:
                break
            candidate = self.calibrate(step, narrower, scale)
            if self._smaller(best, candidate) is best:
                break
            best, index = candidate, index + 1
        best.checks = self.checks
        return best

    def _smaller(self, a: ClipCoding, b: ClipCoding) -> ClipCoding:
        """The smaller of two codings that meet the target (else the one that does)."""
        if (a.error[0] <= self.target) != (b.error[0] <= self.target):
            return a if a.error[0] <= self.target else b
        return a if a.size <= b.size else b

    def calibrate(self, step: float, band: float, scale: float) -> ClipCoding:
        """The coarsest coding at `band` that meets the target on every frame, starting at `step`.

        Each trial is scored end to end, the proxy factor updated from the score, and the step
        searched again on the rescaled proxy, until the true error lands within
        [CALIBRATED_LOW, 1] x target or two steps BRACKET apart straddle it. Long clips calibrate
        on the sampled frames first, then on every frame as written.
        """
        whole = self.sample.step == 1  # the sample is every frame: calibrate as written at once
        best = coding = None  # the coarsest coding that met the target on every frame; the last one scored
        passed = failed = None  # the coarsest step known to meet the target, the finest known to miss it
        for _ in range(MAX_CALIBRATIONS):
            coded = self.code(step, band)
            if whole:
                coding = self.final(coded, scale)
                measured = coding.error[0]
                if measured <= self.target and (best is None or coded.pose_step > best.coded.pose_step):
                    best = coding
            else:
                measured = self.sampled_error(coded)
            predicted = self.proxy(coded.pose_step, coded.root_step, band)
            if predicted > 0 and measured > 0:
                scale = measured / predicted
            if measured <= self.target:
                passed = step if passed is None else max(passed, step)
            else:
                failed = step if failed is None else min(failed, step)
            settled = failed is not None and passed is not None and failed <= passed * (1 + BRACKET)
            close = measured <= self.target and (measured >= CALIBRATED_LOW * self.target or step >= STEP_RANGE[1])
            if settled or close:
                if whole:
                    break
                whole, step, passed, failed = True, passed, None, None  # calibrated on the sample: now every frame
                continue
            step = self.step_for(band, scale, guess=step)
            if failed is not None and step >= failed:  # the proxy, even rescaled, disagrees: bisect
                step = math.sqrt(passed * failed) if passed is not None else failed * (1 - BRACKET)
            elif passed is not None and step <= passed:
                step = math.sqrt(passed * failed) if failed is not None else passed * (1 + BRACKET)
        if best is not None:
            best.proxy_scale, best.checks = scale, self.checks
            return best
        if coding is None or coding.coded.pose_step != float(np.float32(step)):
            coding = self.final(self.code(step, band), scale)
        return self.tightened(coding, band)


def _admissible(error, target: float, band: float) -> bool:
    """Whether dropping the top of `band` alone (the finest step) leaves the quantiser enough of
    the budget: at most MAX_TRUNCATION_SHARE of `target` (cheap to score, so such bands are
    never step-searched)."""
    return error(STEP_RANGE[0], band) <= MAX_TRUNCATION_SHARE * target


def _sized_step(code, error, target: float, band: float, guess: float | None, low: float = STEP_RANGE[0],
                high: float = STEP_RANGE[1]) -> tuple[float, int] | None:
    """(step, bytes) of the coarsest step in [low, high] whose `error` at `band` meets `target`,
    or None if even `low` misses."""
    step, err = largest_step(lambda s: error(s, band), target, low, high, rel_tol=STEP_TOLERANCE, guess=guess,
                             close=PROXY_CLOSE)
    return None if err > target else (step, len(code(step, band).payload()))


def _smallest_near_band(code, error, target: float, start: int, guess: float) -> tuple[float, float]:
    """`_smallest_over_bands` as a local search from BANDS[start]: narrower bands, then wider
    ones, while each comes out smaller. A clip's best band follows its motion more than its
    basis, so the band another basis picked is a close start: two or three bands are tried
    instead of the whole sweep."""
    def tried(i: int, guess: float) -> tuple[float, int] | None:
        return _sized_step(code, error, target, BANDS[i], guess) if _admissible(error, target, BANDS[i]) else None

    best = tried(start, guess)
    if best is None:
        return _smallest_over_bands(code, error, target)
    index = start
    for direction in (1, -1):  # narrower, then (if that did not pay) wider
        i = start + direction
        while 0 <= i < len(BANDS):
            candidate = tried(i, best[0])
            if candidate is None or candidate[1] >= best[1]:
                break
            best, index, i = candidate, i, i + direction
        if index != start:
            break
    return best[0], BANDS[index]


def _smallest_over_bands(code, error, target: float) -> tuple[float, float]:
    """(step, band) of the smallest coding whose `error` is within `target` (see code_clip);
    `code` and `error` take (step, band).

    Bands whose truncation alone takes too much of the budget are never step-searched
    (`_admissible`). Sizes fall as the band narrows until the step must shrink fast, so the
    search starts at the narrowest admissible band and widens while the size keeps falling.
    """
    # BANDS narrow as i grows and the truncation error grows with them; BANDS[0] keeps everything
    widest, narrowest = 0, len(BANDS) - 1
    if not _admissible(error, target, BANDS[narrowest]):
        while narrowest - widest > 1:
            middle = (widest + narrowest) // 2
            widest, narrowest = (middle, narrowest) if _admissible(error, target, BANDS[middle]) else (widest, middle)
        narrowest = widest
    best, best_size = None, None
    low, high, guess = *STEP_RANGE, STEP_GUESS * target
    for band in BANDS[narrowest::-1]:
        sized = _sized_step(code, error, target, band, guess, low, high)
        if sized is None:
            break
        step, size = sized
        if best is not None and size >= best_size:
            break
        best, best_size = (step, band), size
        low, high, guess = step, step * 8, step * 1.25  # a wider band allows a coarser step
    return best if best is not None else (STEP_RANGE[0], 1.0)
