"""The compiled decode tail and error check (`motion.compiled`, `representations.weighted.DecodeTail`)
against the numpy code they mirror: `Representation.inverse`, `positions.true_twists`,
`kinematics.forward` and `metrics.joint_distances`, on real clips of three kinds of skeleton, for
every registered representation; and a representation registered here, which decodes through its
own decoder or is refused.

Poses are disturbed as a coding leaves them (white noise, a smooth drift) and far more (a drift
of 20-50 cm), which forces other Euler branches, unwrapping and twist flips. Sampled frames
(every 8th) are decoded as the encoder's check decodes them: continuity follows the frames given.
"""

from __future__ import annotations

from functools import partial

import numpy as np
import pytest

from mocapzip.inputs.clip import ClipReader
from mocapzip.inputs.discover import find_clips
from mocapzip.motion import compiled, rotations
from mocapzip.motion.kinematics import forward
from mocapzip.motion.metrics import joint_distances
from mocapzip import stages
from mocapzip.representations import Aligned, Encoded, Representation
from mocapzip.representations.aligned import position_columns
from mocapzip.representations.positions import (DegeneratePose, MarkerDecoder, _across, flips_from_ranges,
                                                flip_ranges, true_twists)
from mocapzip.representations.weighted import channels_from_weighted
from mocapzip.stages import stage_ids

CLIPS = {  # relative to ../shared/data: CMU; HDM05; Vicon Blade (short bones, 'f' notation, CRLF)
    "cmu": "cmu/07/07_03.amc",
    "hdm05": "hdm05/bd/HDM_bd_depositFloorR_001_120.amc",
    "blade": "other-vicon-blade/walk_200fps/walkMoCapVideo.amc",
}
REPRESENTATIONS = [(name, axes_from_positions) for name in stage_ids("representation", written_only=True)
                   for axes_from_positions in (True, False)]
VALUES_TOLERANCE = 1e-9  # degrees (or radians): seen up to 2e-11 on the large drift
ERROR_TOLERANCE = 1e-9  # cm: seen up to 4e-13


def load(shared_data, name: str, representation: str, axes_from_positions: bool, frames: int = 600):
    path = shared_data / CLIPS[name]
    source = next(s for s in find_clips([path.parent]) if s.motion == path)
    clip = ClipReader(representation, axes_from_positions=axes_from_positions).read(source)
    n = min(frames, clip.motion.n_frames)
    clip.motion.values = clip.motion.values[:n]
    clip.positions = clip.positions[:n]
    clip.encoded.poses = clip.encoded.poses[:n]
    if clip.encoded.root is not None:
        clip.encoded.root = clip.encoded.root[:n]
    clip.__dict__.pop("poses", None)
    return clip


def disturbed(clip, kind: str, seed: int = 0):
    """Weighted poses and root as a coding leaves them ('noise', 'smooth') or far worse ('large')."""
    rng = np.random.default_rng(seed)
    poses, root = clip.poses, clip.root
    n = len(poses)
    if kind == "noise":
        return (poses + rng.normal(0, 0.3, poses.shape),
                None if root is None else root + rng.normal(0, 1, root.shape) * [0.3, 0.3, 0.3, 0.003])
    size = 0.6 if kind == "smooth" else 6.0
    kernel = np.exp(-0.5 * (np.arange(-30, 31) / 10.0) ** 2)
    kernel /= np.sqrt((kernel ** 2).sum())

    def drift(shape):
        noise = rng.normal(0, 1, (n + 60,) + shape[1:])
        return np.apply_along_axis(lambda c: np.convolve(c, kernel, "valid"), 0, noise)[:n]

    return (poses + size * drift(poses.shape),
            None if root is None else root + drift(root.shape) * np.array([0.3, 0.3, 0.3, 0.003]) * size / 0.3)


def numpy_round_as_written(values: np.ndarray, style) -> np.ndarray:
    """What the AMC text of `values` reads back as, in numpy: the definition the kernel follows."""
    if style.notation == "f":
        return np.round(values, style.digits)
    with np.errstate(divide="ignore", over="ignore", invalid="ignore"):  # 5e-324 overflows, as in the kernel
        exponent = np.floor(np.log10(np.abs(values)))
        scale = 10.0 ** (style.digits - 1 - np.where(np.isfinite(exponent), exponent, 0))
        return np.round(values * scale) / scale


def numpy_score(clip, poses, root, frames, final: bool):
    """LoadedClip._score in numpy: (values, (mean, max) cm, TwistChoice)."""
    twist = true_twists(clip.model, clip.motion.values[frames], clip.layout) if clip.axes_from_positions else None
    values = clip.representation.inverse(clip.model, type(clip.encoded)(poses / clip.weights, root,
                                                                        {**clip.encoded.params, "twist": twist}),
                                         clip.layout)
    if final:
        values = numpy_round_as_written(values, clip.motion.style)
    distances = joint_distances(clip.positions[frames], forward(clip.model, values, clip.layout).positions)
    return values, (float(distances.mean()), float(distances.max())), twist


@pytest.mark.parametrize("name", sorted(CLIPS))
@pytest.mark.parametrize("representation,axes_from_positions", REPRESENTATIONS)
@pytest.mark.parametrize("kind", ["noise", "smooth", "large"])
def test_score_agrees_with_numpy(shared_data, name, representation, axes_from_positions, kind):
    check_score_agrees_with_numpy(load(shared_data, name, representation, axes_from_positions), kind)


def check_score_agrees_with_numpy(clip, kind: str) -> None:
    """The clip's compiled scores and decode, of poses disturbed by `kind`, against numpy's."""
    poses, root = disturbed(clip, kind)
    # the searches score sampled or whole clips unrounded; the final check, whole clips as written
    for frames, final in ((slice(None, None, 8), False), (slice(None), False), (slice(None), True)):
        sampled_poses, sampled_root = poses[frames], None if root is None else root[frames]
        expected_values, expected_error, expected_twist = numpy_score(clip, sampled_poses, sampled_root,
                                                                      frames, final)
        error = (clip.final_check(sampled_poses, sampled_root).error if final
                 else clip.error(sampled_poses, sampled_root, frames))
        assert error == pytest.approx(expected_error, abs=ERROR_TOLERANCE)
        assert error[0] > 0.05  # the disturbance shows: the comparison is not between two zeros
        values, twist = clip._decode(sampled_poses, sampled_root, frames)
        if final:
            compiled.round_as_written(values, clip.motion.style.notation == "f", clip.motion.style.digits)
        np.testing.assert_allclose(values, expected_values, rtol=0, atol=VALUES_TOLERANCE)
        if twist is not None and kind != "large":  # far off, ties between the two solutions fall either way
            for j, flags in expected_twist.flips.items():
                np.testing.assert_array_equal(twist.flips[j], flags)


@pytest.mark.parametrize("name", ["cmu", "hdm05"])  # the Blade skeleton has no 2-dof solved bone
def test_decoder_follows_the_stored_flips(shared_data, name):
    """Decoding with the flips the encoder stored gives the channels the encoder scored."""
    clip = load(shared_data, name, "aligned", True)
    poses, root = disturbed(clip, "large", seed=3)
    _, twist = clip._decode(poses, root, slice(None))
    assert any(flags.any() for flags in twist.flips.values()), "the drift should flip some twists"
    encoder_values, _ = clip.decode_tail.decoder.channels(poses, root, reference=clip._originals(slice(None))[1])
    stored = flips_from_ranges(flip_ranges(twist.flips, clip.model), clip.model, len(poses))
    params = {**clip.encoded.params, "twist": stored}
    decoded = channels_from_weighted(clip.model, clip.representation, clip.layout, poses, root, params,
                                     clip.axis_weight_cm)
    np.testing.assert_array_equal(decoded, encoder_values)
    numpy_decoded = clip.representation.inverse(
        clip.model, type(clip.encoded)(poses / clip.weights, root, params), clip.layout)
    np.testing.assert_allclose(decoded, numpy_decoded, rtol=0, atol=VALUES_TOLERANCE)


def test_direction_lengths_are_numpys():
    """The lengths `compiled.directions_clear` compares, bit for bit those of `check_directions`."""
    rng = np.random.default_rng(5)
    x = rng.normal(size=(2000, 3)) * 10.0 ** rng.uniform(-8, 12, (2000, 1))
    y = rng.normal(size=(2000, 3))
    lengths = np.array([compiled._length(*v) for v in x])
    across = np.array([compiled._across_length(*u, *v) for u, v in zip(x, y)])
    np.testing.assert_array_equal(lengths, np.linalg.norm(x, axis=-1))
    np.testing.assert_array_equal(across, np.linalg.norm(_across(x, y), axis=-1))


@pytest.mark.parametrize("name", sorted(CLIPS))
@pytest.mark.parametrize("axes_from_positions", [True, False])
def test_the_compiled_direction_check_refuses_what_numpy_refuses(shared_data, name, axes_from_positions,
                                                                 monkeypatch):
    """`compiled.directions_clear` stands in for `check_directions`' numpy code: poses shrunk until
    their shortest direction is MIN_DIRECTION, then by one part in 2**52 at a time across it, pass
    or fail both the same."""
    clip = load(shared_data, name, "aligned", axes_from_positions, frames=40)
    decoder, kernel = clip.decode_tail.decoder, compiled.directions_clear

    def refused(poses, compiled_check) -> bool:
        monkeypatch.setattr(compiled, "directions_clear", compiled_check)
        try:
            decoder.check_directions(poses)
        except DegeneratePose:
            return True
        return False

    def numpy_refuses(poses) -> bool:
        return refused(poses, lambda *args: False)  # the kernel says "look": numpy decides

    def compiled_refuses(poses) -> bool:
        clear = []
        refused(poses, lambda *args: clear.append(kernel(*args)) or True)  # the kernel's verdict, numpy skipped
        return not clear[0]

    low, high = 0.0, 1.0  # the scale at which numpy starts to refuse, by bisection
    for _ in range(1100):
        if high - low <= high * 2.0**-53:
            break
        middle = (low + high) / 2
        low, high = (low, middle) if not numpy_refuses(clip.poses * middle) else (middle, high)
    outcomes = [(compiled_refuses(clip.poses * scale), numpy_refuses(clip.poses * scale))
                for scale in high * (1 + np.arange(-20, 21) * 2.0**-52)]
    assert {numpy for _, numpy in outcomes} == {True, False}  # the threshold was crossed
    assert all(ours == numpy for ours, numpy in outcomes), outcomes
    assert not compiled_refuses(clip.poses) and compiled_refuses(clip.poses * 0)


# --------------------------------------------------------------------------- a representation registered here

OFFSET_CM = 10.0  # the toy moves every stored joint position by this much: another's decode lands far off


def offset_to_aligned(model, poses: np.ndarray) -> np.ndarray:
    out = np.array(poses, dtype=np.float64)
    out[:, : position_columns(model)] -= OFFSET_CM
    return out


@pytest.fixture
def registry(monkeypatch):
    """The registry as it is; what a test registers is gone after it."""
    monkeypatch.setattr(stages, "_REGISTRY", {kind: dict(classes) for kind, classes in stages._loaded().items()})


def test_a_new_representation_decodes_through_its_own_decoder(shared_data, registry):
    """A representation the tail has never heard of is decoded by the decoder it declares: the
    compiled scores and decode agree with its own inverse, not with `aligned`'s, whose code it extends."""

    @stages.register
    class Offset(Aligned):
        codec_id = "offset"

        def forward(self, model, motion):
            encoded = super().forward(model, motion)
            encoded.poses[:, : position_columns(model)] += OFFSET_CM
            return encoded

        def inverse(self, model, encoded, layout):
            poses = offset_to_aligned(model, encoded.poses)
            return super().inverse(model, Encoded(poses, encoded.root, encoded.params), layout)

        def decoder(self, tables, params, axis_weight_cm):
            return MarkerDecoder(tables, self.column_weights(tables.model, tables.layout, axis_weight_cm), False,
                                 self.axes_from_positions,
                                 to_markers=partial(offset_to_aligned, tables.model))

    clip = load(shared_data, "cmu", "offset", True)
    assert isinstance(clip.representation, Offset)
    check_score_agrees_with_numpy(clip, "noise")
    poses, root = disturbed(clip, "noise")
    as_aligned = channels_from_weighted(clip.model, Aligned(True), clip.layout, poses, root, clip.encoded.params,
                                        clip.axis_weight_cm)
    own = channels_from_weighted(clip.model, clip.representation, clip.layout, poses, root, clip.encoded.params,
                                 clip.axis_weight_cm)
    assert np.abs(own - as_aligned).max() > 1.0  # degrees: aligned's path would not have given it


def test_a_representation_with_its_own_inverse_and_not_its_own_decoder_is_refused(registry):
    """Extending a representation's inverse without its decoder would decode it down the parent's path."""
    with pytest.raises(TypeError, match="Offset defines its own inverse but not its decoder.*as Aligned does"):
        class Offset(Aligned):
            codec_id = "offset"

            def inverse(self, model, encoded, layout):
                return super().inverse(model, encoded, layout)


def test_a_representation_without_a_decode_cannot_be_registered(registry):
    class Bare(Representation):
        codec_id = "bare"

        def forward(self, model, motion):
            return Encoded(np.array(motion.values, dtype=np.float64))

    with pytest.raises(TypeError, match="representation 'bare': Bare does not define column_weights, decoder, "
                                        "inverse, joint_position_columns"):
        stages.register(Bare)
    assert "bare" not in stage_ids("representation")


@pytest.mark.parametrize("name", sorted(CLIPS))
def test_forward_kinematics_matches_numpy(shared_data, name):
    """The original joint positions a clip is scored against come from the compiled kinematics."""
    clip = load(shared_data, name, "aligned", True, frames=2000)
    expected = forward(clip.model, clip.motion.values, clip.layout).positions
    np.testing.assert_allclose(clip.positions, expected, rtol=0, atol=1e-9)
    assert clip.positions.shape == expected.shape


@pytest.mark.parametrize("name", sorted(CLIPS))
def test_probed_kinematics_are_the_full_kinematics_bit_for_bit(shared_data, name):
    """The least patch's Jacobian makes again only the joints a moved column turns: its
    positions must be those of the whole skeleton's kinematics exactly, or archive bytes move."""
    clip = load(shared_data, name, "aligned", True, frames=40)
    tail, values = clip.decode_tail, clip.motion.values[::4]
    cols = np.array([0, 3, 5, tail.width // 2, tail.width - 1])
    shifts = np.array([1e-3, -2e-3, 0.5, 1e-3, 7.0])
    shifted = np.repeat(values[:, None, :], len(cols), axis=1)
    shifted[:, np.arange(len(cols)), cols] += shifts
    expected = tail.positions(shifted.reshape(-1, tail.width)).reshape(len(values), len(cols), -1, 3)
    np.testing.assert_array_equal(tail.probed_positions(values, cols, shifts), expected)


def test_rounding_as_written_matches_numpy():
    rng = np.random.default_rng(7)
    values = np.concatenate([rng.normal(0, 1, 4000) * 10.0 ** rng.integers(-6, 6, 4000),
                             [0.0, -0.0, 0.5, -0.5, 1.5, 2.5, 123456.5, 1e-300, 5e-324, 179.99995, -180.0]])
    for notation, digits in (("g", 6), ("g", 4), ("f", 6), ("f", 3)):
        style = type("Style", (), {"notation": notation, "digits": digits})
        rounded = values.copy()[None]
        compiled.round_as_written(rounded, notation == "f", digits)
        np.testing.assert_array_equal(rounded[0], numpy_round_as_written(values, style))


@pytest.mark.parametrize("n", [0, 1, 7, 8, 9, 127, 128, 129, 255, 256, 1000, 4097, 100_003])
def test_pairwise_sum_is_numpys(n):
    """The mean error is summed as numpy sums, so scores match `distances.mean()` bit for bit."""
    values = np.random.default_rng(n).exponential(1.0, n)
    assert compiled.np_sum(values) == np.sum(values)


def test_kernel_constants_are_the_numpy_codes():
    """numba freezes globals when it compiles, so the kernels keep their own copies of these."""
    assert compiled.GIMBAL == rotations._GIMBAL
    assert compiled.TWO_DOF_ROUNDS == rotations._TWO_DOF_ROUNDS
    assert compiled.TWO_DOF_TOLERANCE == rotations._TWO_DOF_TOLERANCE
