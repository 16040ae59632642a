"""Every registered pipeline stage against the contract of its kind (tests/common.py), and against
its frozen fixture (tests/golden/stages/, written once by tests/make_stage_fixtures.py).

The stages come from the registry (`mocapzip.stages`), not from a list here: a newly registered
stage is checked as soon as it exists, and fails `test_every_stage_has_a_fixture` until its
fixture is written. Decode-only stages (`decode_only`, an old format's) get the config and repr
checks and their fixture, not an encode round trip.
"""

from __future__ import annotations

import json
import pickle

import numpy as np
import pytest

from common import (STAGE_FIXTURES, TRANSFORM_DTYPES, assert_bits_equal, check_coefficient_coder_round_trip,
                    check_config_round_trip, check_lossless_round_trip, check_matrices_equal,
                    check_quantiser_round_trip, check_repr, check_representation_round_trip,
                    check_transform_round_trip, check_unknown_id_refused, encoder_twists, fixture_matrices,
                    fixture_name, kind_slug, load_clip, load_fixture, lossless_stream_version)
from mocapzip.codec import lossless
from mocapzip.codec.entropy.coefficients import Priors, matrix_stream_version
from mocapzip.representations.base import Encoded
from mocapzip.representations.positions import flips_from_ranges
from mocapzip.representations.weighted import DecodeTail
from mocapzip.stages import KINDS, get_stage, stage_classes, stage_ids

# Configs besides every stage's defaults, for parameters whose values take other code paths.
# An entry whose id is no longer registered fails `test_example_configs_name_registered_stages`.
EXAMPLE_CONFIGS = {
    "transform": [{"id": "dwt", "wavelet": "haar", "level": 2}, {"id": "dwt", "wavelet": "bior2.2", "level": None},
                  {"id": "dwt", "wavelet": "sym5", "level": 0}, {"id": "dwt", "wavelet": "coif2", "level": 40},
                  {"id": "poly", "knot_spacing": 1}, {"id": "poly", "knot_spacing": 7},
                  {"id": "poly", "knot_spacing": 512}],
    "quantiser": [{"id": "uniform", "step": 0.25, "dead_zone": 0.125}, {"id": "uniform", "step": 1e-3, "dead_zone": 0.0},
                  {"id": "uniform", "step": 7.5, "dead_zone": 0.45}],
}
# Stream versions each decoder must still read, so each needs a fixture.
STREAM_VERSIONS = {("lossless coder", "decimal"): lossless._KNOWN_LAYOUTS}


def stage_cases(kind: str, encodable_only: bool = False) -> list:
    """pytest params (kind, id, config or None for the defaults) of every registered stage of `kind`,
    plus its example configs; representations also with axes_from_positions=True. Stages are built
    inside the tests, so one that cannot be built fails its own tests, not the collection."""
    cases = []
    for codec_id, cls in stage_classes(kind).items():
        if encodable_only and getattr(cls, "decode_only", False):
            continue
        configs = [None] + [c for c in EXAMPLE_CONFIGS.get(kind, []) if c["id"] == codec_id]
        if kind == "representation":
            configs.append({"id": codec_id, "axes_from_positions": True})
        for config in configs:
            label = codec_id if config is None else ",".join(f"{k}={v}" for k, v in config.items() if k != "id")
            cases.append(pytest.param(kind, codec_id, config, id=f"{kind_slug(kind)}:{codec_id}"
                                      + ("" if config is None else f"[{label}]")))
    return cases


def build(kind: str, codec_id: str, config):
    return stage_classes(kind)[codec_id]() if config is None else get_stage(kind, config)


ALL_STAGES = [case for kind in KINDS for case in stage_cases(kind)]
FIXTURES = sorted(STAGE_FIXTURES.glob("*.npz"))


# --------------------------------------------------------------------------- the registry


@pytest.mark.parametrize("kind", KINDS)
def test_every_kind_has_a_stage(kind):
    """A kind without stages would leave a hole in every archive's chain."""
    assert stage_classes(kind), f"no {kind} is registered"


@pytest.mark.parametrize("kind", KINDS)
def test_unknown_ids_are_refused(kind):
    check_unknown_id_refused(kind)


def test_example_configs_name_registered_stages():
    """A stage renamed or removed must not leave its examples silently unused."""
    for kind, configs in EXAMPLE_CONFIGS.items():
        for config in configs:
            assert config["id"] in stage_classes(kind), f"{kind} example {config} names no registered stage"


@pytest.mark.parametrize(("kind", "codec_id", "config"), ALL_STAGES)
def test_config_round_trip(kind, codec_id, config):
    stage = build(kind, codec_id, config)
    assert stage.kind == kind and stage.codec_id == codec_id
    check_config_round_trip(stage)


@pytest.mark.parametrize(("kind", "codec_id", "config"), ALL_STAGES)
def test_repr(kind, codec_id, config):
    check_repr(build(kind, codec_id, config))


@pytest.mark.parametrize("kind", KINDS)
def test_decode_only_stages_cannot_encode(kind):
    """An old format's stage only reads: no path may write a layout no current reader expects."""
    for codec_id, cls in stage_classes(kind).items():
        if getattr(cls, "decode_only", False):
            assert not hasattr(cls, "encode"), f"{kind} {codec_id!r} is decode only but has encode"
            assert hasattr(cls, "decode")
            assert codec_id not in stage_ids(kind, written_only=True)
        else:
            assert codec_id in stage_ids(kind, written_only=True)


def test_equal_stages_hash_alike_with_signed_zero():
    """eq/hash consistency where a parameter's two spellings compare equal but print differently."""
    a = get_stage("quantiser", {"id": "uniform", "step": 1.0, "dead_zone": -0.0})
    b = get_stage("quantiser", {"id": "uniform", "step": 1.0, "dead_zone": 0.0})
    assert a == b
    assert hash(a) == hash(b)


# --------------------------------------------------------------------------- kind round trips


@pytest.mark.parametrize("dtype", TRANSFORM_DTYPES, ids=lambda d: np.dtype(d).name)
@pytest.mark.parametrize(("kind", "codec_id", "config"), stage_cases("transform"))
def test_transform_round_trip(kind, codec_id, config, dtype):
    check_transform_round_trip(build(kind, codec_id, config), dtype)


@pytest.mark.parametrize(("kind", "codec_id", "config"), stage_cases("quantiser"))
def test_quantiser_round_trip(kind, codec_id, config):
    check_quantiser_round_trip(build(kind, codec_id, config))


@pytest.mark.parametrize(("kind", "codec_id", "config"), stage_cases("coefficient coder", encodable_only=True))
def test_coefficient_coder_round_trip(kind, codec_id, config):
    check_coefficient_coder_round_trip(build(kind, codec_id, config))


@pytest.mark.parametrize(("kind", "codec_id", "config"), stage_cases("lossless coder", encodable_only=True))
def test_lossless_coder_round_trip_on_real_values(kind, codec_id, config, shared_data):
    _, motion = load_clip(shared_data)
    check_lossless_round_trip(build(kind, codec_id, config), motion.values)


@pytest.mark.parametrize(("kind", "codec_id", "config"), stage_cases("representation", encodable_only=True))
def test_representation_round_trip_on_a_real_clip(kind, codec_id, config, shared_data):
    check_representation_round_trip(build(kind, codec_id, config), *load_clip(shared_data))


@pytest.mark.parametrize(("kind", "codec_id", "config"), stage_cases("representation", encodable_only=True))
def test_representation_decode_tail_gives_its_inverse(kind, codec_id, config, shared_data):
    """The decode tail (`mcz decompress`, the encoder's error check) runs the representation's own
    decoder on its weighted poses, and that gives what its inverse gives: a representation is
    never decoded down another's path."""
    representation = build(kind, codec_id, config)
    model, motion = load_clip(shared_data)
    encoded = representation.forward(model, motion)
    encoded.params["twist"] = encoder_twists(model, motion)
    expected = representation.inverse(model, encoded, motion)  # records the twist flips the decoder follows
    axis_weight_cm = 12.0
    weights = representation.column_weights(model, motion, axis_weight_cm)
    assert weights.shape == encoded.poses.shape[1:] and np.all(weights > 0)
    assert representation.joint_position_columns(model).stop <= len(weights)
    tail = DecodeTail(model, representation, motion, encoded.params, axis_weight_cm)
    decoded = tail.decode(encoded.poses * weights, encoded.root, encoded.params["twist"])
    np.testing.assert_allclose(decoded, expected, rtol=0, atol=1e-9)
    # clips go to worker processes with their decode tail
    copy = pickle.loads(pickle.dumps(tail))
    np.testing.assert_array_equal(copy.decode(encoded.poses * weights, encoded.root, encoded.params["twist"]), decoded)


# --------------------------------------------------------------------------- frozen fixtures


def fixture_index() -> dict[tuple[str, str], list[dict]]:
    index: dict[tuple[str, str], list[dict]] = {}
    for path in FIXTURES:
        meta, _ = load_fixture(path)
        index.setdefault((meta["kind"], meta["codec_id"]), []).append(meta)
    return index


def test_every_stage_has_a_fixture():
    """A stage without a frozen stream could change its output unnoticed: run
    tests/make_stage_fixtures.py after registering one (it writes only what is missing)."""
    index = fixture_index()
    missing = [f"{kind} {codec_id!r}" for kind in KINDS for codec_id in stage_classes(kind)
               if (kind, codec_id) not in index]
    assert not missing, f"no fixture in {STAGE_FIXTURES} for {', '.join(missing)}: run tests/make_stage_fixtures.py"
    for (kind, codec_id), versions in STREAM_VERSIONS.items():
        stored = {meta["version"] for meta in index.get((kind, codec_id), [])}
        assert set(versions) <= stored, f"{kind} {codec_id!r}: no fixture for stream versions {set(versions) - stored}"


def test_every_fixture_names_a_registered_stage():
    """Unregistering a stage that has a fixture would leave the streams it wrote unreadable."""
    for (kind, codec_id), metas in fixture_index().items():
        assert codec_id in stage_classes(kind), f"{kind} {codec_id!r} has fixtures but is no longer registered"
        for meta in metas:
            assert get_stage(kind, meta["config"]).get_config() == meta["config"]


def fixture_params(encoder_golden_only: bool = False) -> list:
    params = []
    for path in FIXTURES:
        meta, _ = load_fixture(path)
        if not encoder_golden_only or meta["encoder_golden"]:
            params.append(pytest.param(path, id=path.stem))
    return params


def clip_of(meta: dict, shared_data):
    """The real clip a fixture was made from, checked to be the very values it stored."""
    assert meta["clip"]["frames"] is not None
    return load_clip(shared_data, meta["clip"]["frames"])


def representation_encoded(meta: dict, arrays: dict, model) -> Encoded:
    """The Encoded a reader would hand the inverse: stored matrices, params and twist flips."""
    params = {key[len("param_"):]: (float(value) if value.ndim == 0 else value)
              for key, value in arrays.items() if key.startswith("param_")}
    params["twist"] = flips_from_ranges(meta["twist_ranges"], model, len(arrays["encoded_poses"]))
    return Encoded(arrays["encoded_poses"], arrays.get("encoded_root"), params)


def assert_float_golden(actual: np.ndarray, expected: np.ndarray, what: str) -> None:
    """Equal to the fixture within 1e-9 of its scale: a changed stage differs by far more.

    Not bit for bit: NumPy dispatches float64 sin/cos/arctan2 and matmul kernels at run time by
    CPU, and pocketfft and PyWavelets are compiled per platform, so another CPU differs from the
    machine that wrote the fixtures by a few ulps (measured: 1.3e-15 cm in the representations'
    outputs on an AMD EPYC). Whether an encoder change alters archive bytes is proved on one
    machine, by comparing the archives written before and after it.
    """
    assert actual.shape == expected.shape and actual.dtype == expected.dtype, (actual.shape, actual.dtype)
    scale = max(1.0, float(np.abs(expected).max(initial=0.0)))
    np.testing.assert_allclose(actual, expected, rtol=0, atol=1e-9 * scale, err_msg=f"{what}: the stage changed")


@pytest.mark.parametrize("path", fixture_params())
def test_fixture_decodes(path, shared_data):
    """(a) Every stored stream, as some encoder wrote it once, still decodes to what it held."""
    meta, arrays = load_fixture(path)
    kind = meta["kind"]
    assert path.name.startswith(fixture_name(kind, meta["codec_id"])[: -len(".npz")])  # the name says the stage
    stage = get_stage(kind, meta["config"])
    if kind == "transform":
        assert_float_golden(stage.inverse(arrays["encoded"], len(arrays["encoded"])), arrays["decoded"], "inverse")
        np.testing.assert_allclose(arrays["decoded"], arrays["input"], rtol=0, atol=1e-12 * np.abs(arrays["input"]).max())
    elif kind == "quantiser":
        assert arrays["encoded"].dtype == np.int64
        np.testing.assert_array_equal(stage.dequantise(arrays["encoded"]), arrays["decoded"])  # one IEEE multiply: exact anywhere
    elif kind == "coefficient coder":
        blob = arrays["encoded"].tobytes()
        priors = Priors.decode(arrays["priors"].tobytes()) if "priors" in arrays else None
        matrices = fixture_matrices(arrays)
        if meta["version"] is not None:
            assert matrix_stream_version(blob) == meta["version"]
        check_matrices_equal(stage.decode(blob, [m.shape for m in matrices], priors), matrices)
        check_matrices_equal(stage.decode(blob, None, priors), matrices)
    elif kind == "lossless coder":
        blob = arrays["encoded"].tobytes()
        assert lossless_stream_version(blob) == meta["version"]
        assert_bits_equal(stage.decode(blob), arrays["input"])
        _, motion = clip_of(meta, shared_data)
        assert_bits_equal(arrays["input"], motion.values)  # the reader still gives the values stored
    elif kind == "representation":
        model, motion = clip_of(meta, shared_data)
        assert_bits_equal(arrays["input"], motion.values)
        decoded = stage.inverse(model, representation_encoded(meta, arrays, model), motion)
        assert_float_golden(decoded, arrays["decoded"], "inverse")
        np.testing.assert_allclose(decoded, motion.values, rtol=0, atol=1e-6)
    else:
        pytest.fail(f"no fixture check for kind {kind!r}")


@pytest.mark.parametrize("path", fixture_params(encoder_golden_only=True))
def test_fixture_encoder_is_unchanged(path, shared_data):
    """(b) Encoding the stored input with the stored config gives the stored output (integers and
    bytes exactly, floats within `assert_float_golden`'s tolerance): an encoder whose output
    changes fails here, not in a manual cmp of archives. Streams no encoder
    writes any more (decode-only stages, old versions) have no such golden."""
    meta, arrays = load_fixture(path)
    kind = meta["kind"]
    stage = get_stage(kind, meta["config"])
    assert not getattr(stage, "decode_only", False)
    if kind == "transform":
        assert_float_golden(stage.forward(arrays["input"]), arrays["encoded"], "forward")
    elif kind == "quantiser":
        np.testing.assert_array_equal(stage.quantise(arrays["input"]), arrays["encoded"])
    elif kind == "coefficient coder":
        priors = None
        if "priors" in arrays:
            count = sum(1 for key in arrays if key.startswith("train") and key.endswith("_0"))
            priors = Priors.train([fixture_matrices(arrays, f"train{i}") for i in range(count)])
            assert priors.encode() == arrays["priors"].tobytes(), "Priors.train changed"
        assert stage.encode(fixture_matrices(arrays), priors) == arrays["encoded"].tobytes()
    elif kind == "lossless coder":
        assert stage.encode(arrays["input"]) == arrays["encoded"].tobytes()
    elif kind == "representation":
        model, motion = clip_of(meta, shared_data)
        encoded = stage.forward(model, motion)
        assert_float_golden(encoded.poses, arrays["encoded_poses"], "forward poses")
        assert (encoded.root is None) == ("encoded_root" not in arrays)
        if encoded.root is not None:
            assert_float_golden(encoded.root, arrays["encoded_root"], "forward root")
        stored = {key[len("param_"):] for key in arrays if key.startswith("param_")}
        assert set(encoded.params) == stored
        for key in stored:
            assert_float_golden(np.asarray(encoded.params[key], np.float64), arrays[f"param_{key}"], f"param {key}")
    else:
        pytest.fail(f"no fixture check for kind {kind!r}")


def test_fixtures_hold_no_pickles():
    """np.load(allow_pickle=False) reads every fixture: they are data, never code."""
    assert FIXTURES, f"no fixtures in {STAGE_FIXTURES}"
    for path in FIXTURES:
        meta, arrays = load_fixture(path)
        assert json.loads(json.dumps(meta)) == meta
        assert all(array.dtype != object for array in arrays.values())


def test_from_config_refuses_another_stages_id():
    with pytest.raises(ValueError, match="another stage"):
        stage_classes("transform")["dct"].from_config({"id": "dwt"})
