"""The rate control on real clips: searches on the calibrated proxy, true end-to-end scores only to
calibrate and verify, and every clip within its target as written."""

import math

import pytest

from mocapzip.archive.settings import Settings, checked
from mocapzip.codec.basis import ClassBasis
from mocapzip.codec.clip_stream import reconstruct
from mocapzip.codec.pca import CovarianceAccumulator, PcaBasis
from mocapzip.inputs.clip import load_clips
from mocapzip.inputs.discover import find_clips
from mocapzip.ratecontrol.encode import (BANDS, COARSER_BASES, MAX_CALIBRATIONS, MAX_TRUNCATION_SHARE, STEP_RANGE,
                                         _smallest_near_band, _smallest_over_bands, code_clip, encode_class)
from mocapzip.stages import get_stage


@pytest.fixture(scope="module")
def subject(shared_data):
    """cmu/09 (runs): its clips and a 30-component class basis stored as the codec stores it."""
    settings = checked(Settings())  # its representation as compress resolves it
    clips = load_clips(find_clips([shared_data / "cmu" / "09"]), settings.representation, settings.axis_weight_cm,
                       settings.axes_from_positions)
    accumulator = CovarianceAccumulator(clips[0].poses.shape[1])
    for clip in clips:
        accumulator.add(clip.poses)
    pca = PcaBasis.fit(accumulator)
    steps = ClassBasis.steps_for(pca.variances[:30], 1.0, settings.basis_precision)
    return settings, clips, ClassBasis.quantised(pca.mean, pca.components[:, :30], steps)


@pytest.mark.parametrize("target", [0.5, 1.0, 2.0])
def test_each_clip_lands_just_under_its_target_with_few_true_scores(subject, target):
    settings, clips, basis = subject
    transform = get_stage("transform", settings.transform)
    for clip in clips[:4]:
        coding = code_clip(clip, basis, transform, target, settings.dead_zone)
        assert coding.error[0] <= target, clip.source.motion
        assert coding.error[0] >= 0.95 * target, (clip.source.motion, coding.error)  # no bytes given away
        assert coding.checks <= 3 * MAX_CALIBRATIONS  # a handful of true scores, not one per step tried
        assert coding.proxy_scale > 0
        # the error returned is the end-to-end one of the coding returned, every frame as written
        again = clip.final_check(*reconstruct(coding.coded, basis, transform, settings.dead_zone,
                                              clip.motion.n_frames))
        assert again.error == coding.error and again.twists == coding.twists


def test_a_start_from_the_estimates_replaces_the_first_band_search(subject):
    """`start` (step, band) is where the search begins: from a poor start (the whole band and a step
    far too coarse, or a narrow band, a step far too fine and a factor far off) the clip still lands
    just under its target, verified on every frame."""
    settings, clips, basis = subject
    transform = get_stage("transform", settings.transform)
    clip = clips[0]
    for start, scale in [((30.0, 1.0), 1.0), ((0.01, BANDS[-3]), 2.0)]:
        coding = code_clip(clip, basis, transform, 1.0, settings.dead_zone, start=start, proxy_scale=scale)
        assert 0.95 <= coding.error[0] <= 1.0, (start, coding.error)
        assert coding.checks <= 3 * MAX_CALIBRATIONS


def test_a_class_of_one_short_clip_stores_its_basis_coarser(subject):
    """One short clip cannot earn back a finely stored basis: the class tries it coarser, and the
    coarser basis it keeps still lets the clip meet its target."""
    settings, clips, _ = subject
    clip = min(clips, key=lambda c: c.motion.n_frames)
    transform = get_stage("transform", settings.transform)
    basis, codings = encode_class([clip], transform, settings.coding_target())
    accumulator = CovarianceAccumulator(clip.poses.shape[1])
    accumulator.add(clip.poses)
    variances = PcaBasis.fit(accumulator).variances[: basis.q]
    ratios = basis.steps / ClassBasis.steps_for(variances, settings.error_cm, settings.basis_precision)
    assert any(ratios == pytest.approx(m, rel=1e-6) for m in COARSER_BASES), ratios
    assert codings[0].achieved.mean <= settings.error_cm


class _Sized:
    """A coding whose payload has a given length (what the band searches measure)."""

    def __init__(self, size: int):
        self.size = size

    def payload(self) -> bytes:
        return bytes(self.size)


def band_landscape(best_band: float, floor: float = 0.0):
    """(code, error) of a made-up clip: the error is floor + step / 3 plus a truncation term that
    grows as the band narrows, and the bytes are smallest at `best_band` for the largest allowed step."""
    def error(step: float, band: float) -> float:
        return floor + step / 3 + 0.02 / band

    def code(step: float, band: float) -> _Sized:
        return _Sized(int(1000 / step + 4000 * abs(math.log(band / best_band))))

    return code, error


@pytest.mark.parametrize("best", [0.13, 0.06, 1.0])
@pytest.mark.parametrize("start", [0, 5, 9])
def test_the_near_band_search_walks_to_the_band_the_sweep_finds(best, start):
    code, error = band_landscape(best)
    swept = _smallest_over_bands(code, error, 1.0)
    assert swept[1] == best
    near = _smallest_near_band(code, error, 1.0, start, 2.0)
    assert near[1] == best and near[0] == pytest.approx(swept[0], rel=0.02)


def test_the_near_band_search_falls_back_to_the_sweep_if_its_start_cannot_meet_the_target():
    code, error = band_landscape(0.2)
    narrowest = len(BANDS) - 1  # truncation alone there: 0.02 / 0.02 = 1 > MAX_TRUNCATION_SHARE
    assert error(STEP_RANGE[0], BANDS[narrowest]) > MAX_TRUNCATION_SHARE
    assert _smallest_near_band(code, error, 1.0, narrowest, 2.0) == _smallest_over_bands(code, error, 1.0)
