"""The rate control on real clips: searches on the calibrated proxy, true end-to-end scores only to
calibrate and verify, and every clip within its target as written."""

import pytest

from mocapzip.archive.settings import Settings
from mocapzip.codec.basis import ClassBasis
from mocapzip.codec.clip_stream import reconstruct
from mocapzip.codec.pca import CovarianceAccumulator, PcaBasis
from mocapzip.inputs.clip import load_clips
from mocapzip.inputs.discover import find_clips
from mocapzip.ratecontrol.encode import MAX_CALIBRATIONS, code_clip
from mocapzip.stages import get_stage


@pytest.fixture(scope="module")
def subject(shared_data):
    """cmu/09 (runs): its clips and a 30-component class basis stored as the codec stores it."""
    settings = Settings()
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
        assert coding.error[0] <= target, clip.source.amc
        assert coding.error[0] >= 0.95 * target, (clip.source.amc, coding.error)  # no bytes given away
        assert coding.checks <= 3 * MAX_CALIBRATIONS  # a handful of true scores, not one per step tried
        assert coding.proxy_scale > 0
        # the error returned is the end-to-end one of the coding returned, every frame as written
        again = clip.final_check(*reconstruct(coding.coded, basis, transform, settings.dead_zone,
                                              clip.motion.n_frames))
        assert again.error == coding.error and again.twists == coding.twists

