"""Contract checks every pipeline stage must pass, shared as numcodecs' tests/common.py shares
its codec checks: tests/test_stage_contracts.py calls them for every stage the registry
(`mocapzip.stages`) knows, and tests/make_stage_fixtures.py builds its fixtures with the
helpers at the end of this file, so the script and the tests read the fixtures alike.

Each check raises AssertionError with what broke; none of them knows a particular stage id.
"""

from __future__ import annotations

import dataclasses
import json
import os
from functools import lru_cache
from pathlib import Path

import numpy as np
import pytest

from mocapzip.formats.amc import Motion, read_amc
from mocapzip.formats.asf import read_asf
from mocapzip.motion.skeleton import SkeletonModel
from mocapzip.stages import KINDS, get_stage

STAGE_FIXTURES = Path(__file__).resolve().parent / "golden" / "stages"

# The real clip of the contract tests and of the fixtures (relative to ../shared/data).
CLIP_ASF = "cmu/09/09.asf"
CLIP_AMC = "cmu/09/09_01.amc"
FIXTURE_FRAMES = 60  # the fixtures keep the first 60 frames: small files, still real decimals and motion

TRANSFORM_LENGTHS = (1, 2, 3, 7, 64, 101, 512)  # 1-3: degenerate wavelet levels; odd ones: DWT's odd sample
TRANSFORM_DTYPES = (np.float32, np.float64)
# Reconstruction error allowed, times the largest |value| (as tests/test_codec_temporal.py).
TRANSFORM_TOLERANCE = {np.dtype(np.float32): 1e-5, np.dtype(np.float64): 1e-12}
# forward + inverse of a representation on a real clip: every channel back to this (degrees
# or cm); measured 5e-13 on 09_01, so 1e-6 only leaves room for other platforms' last bits.
REPRESENTATION_TOLERANCE = 1e-6


# --------------------------------------------------------------------------- every stage


def check_config_round_trip(stage) -> None:
    """get_config() -> JSON -> get_stage() gives an equal stage: an archive stores only the JSON,
    so anything lost here is a stream a reader cannot decode."""
    config = stage.get_config()
    assert isinstance(config, dict) and config.get("id") == stage.codec_id, config
    assert stage.kind in KINDS, stage.kind
    text = json.dumps(config, allow_nan=False)  # an archive's meta is strict JSON
    loaded = json.loads(text)
    assert loaded == config, f"{config!r} does not survive JSON ({text})"
    rebuilt = get_stage(stage.kind, loaded)
    assert type(rebuilt) is type(stage)
    assert rebuilt == stage and not (rebuilt != stage)
    assert rebuilt.get_config() == config
    assert repr(rebuilt) == repr(stage)
    assert hash(rebuilt) == hash(stage), "equal stages must hash alike (they key caches and sets)"
    assert type(stage).from_config(loaded) == stage
    without_id = {key: value for key, value in loaded.items() if key != "id"}
    assert type(stage).from_config(without_id) == stage  # "id" is optional for from_config
    assert stage != object() and stage != config
    with pytest.raises(ValueError):
        type(stage).from_config({**loaded, "no_such_parameter": 1})
    with pytest.raises(ValueError):
        get_stage(stage.kind, {**loaded, "no_such_parameter": 1})


def check_repr(stage) -> None:
    """repr names the class and every parameter with its value, so a log line or a failing test
    says exactly which stage it was (checked by text, never by eval)."""
    text = repr(stage)
    name = type(stage).__name__
    assert text.startswith(f"{name}(") and text.endswith(")"), text
    params = {key: value for key, value in stage.get_config().items() if key != "id"}
    for key, value in params.items():
        assert f"{key}={value!r}" in text, f"{text} does not show {key}={value!r}"
    if not params:
        assert text == f"{name}()", text


def check_unknown_id_refused(kind: str) -> None:
    """A config naming no registered stage is a ValueError, which readers turn into "damaged archive"."""
    for config in ({"id": "no-such-stage"}, {}, {"id": None}, {"id": ["dct"]}):
        with pytest.raises(ValueError):
            get_stage(kind, config)


# --------------------------------------------------------------------------- transforms


def check_transform_round_trip(transform, dtype, lengths=TRANSFORM_LENGTHS, n_curves: int = 3) -> None:
    """Exactly T coefficients for T frames, perfect reconstruction, dtype kept (PyWavelets'
    tests check the same): a coefficient index must fit the frame count, and float32 input
    must not silently double in memory."""
    dtype = np.dtype(dtype)
    tolerance = TRANSFORM_TOLERANCE[dtype]
    for n in lengths:
        rng = np.random.default_rng(n)
        x = np.cumsum(rng.normal(size=(n, n_curves)), axis=0).astype(dtype)  # smooth, as motion curves
        original = x.copy()
        coefs = transform.forward(x)
        assert coefs.shape == x.shape, f"{transform!r}, T={n}: {coefs.shape} coefficients for {x.shape}"
        assert coefs.dtype == dtype, f"{transform!r}, T={n}: {dtype} in, {coefs.dtype} out"
        assert not np.shares_memory(coefs, x)
        restored = transform.inverse(coefs, n)
        assert restored.shape == x.shape and restored.dtype == dtype
        assert not np.shares_memory(restored, coefs)
        np.testing.assert_array_equal(x, original, err_msg="forward changed its input")
        scale = max(1.0, float(np.abs(x).max()))
        np.testing.assert_allclose(restored, x, rtol=0, atol=tolerance * scale,
                                   err_msg=f"{transform!r}, T={n}, {dtype}")
        if getattr(transform, "orthonormal", False):  # the encoder sets error budgets in coefficient space
            energy = np.sum(x.astype(np.float64) ** 2)
            assert np.sum(coefs.astype(np.float64) ** 2) == pytest.approx(energy, rel=100 * tolerance, abs=1e-30)
        # one curve alone: as a column of many (the codec transforms whole matrices)
        np.testing.assert_allclose(transform.forward(x[:, 0]), coefs[:, 0], rtol=0, atol=tolerance * scale)
        with pytest.raises(ValueError):
            transform.inverse(coefs, n + 1)  # a coefficient count that is not the frame count


# --------------------------------------------------------------------------- quantisers


def quantiser_inputs() -> np.ndarray:
    """Coefficients of every size, signs and zeros, and values exactly on bin edges."""
    rng = np.random.default_rng(11)
    parts = [rng.normal(scale=scale, size=500) for scale in (1e-6, 1e-2, 1.0, 1e2, 1e6)]
    edges = (np.arange(-20, 21) + 0.5) * 0.25  # rounding ties for steps of 0.25 and 0.5
    return np.concatenate(parts + [edges, [0.0, -0.0, 1e-300, -1e-300]])


def check_quantiser_round_trip(quantiser) -> None:
    """|x - dequantise(quantise(x))| <= (0.5 + dead_zone) * step: the error bound the lossy
    encoder's error search relies on, and integers that the coefficient coders take."""
    step, dead_zone = quantiser.step, quantiser.dead_zone
    x = quantiser_inputs()
    x = np.concatenate([x, x * step])  # on the quantiser's own scale too
    x = x[np.abs(x) / step < 2.0**50]  # far below the int64 limit the quantiser refuses beyond
    q = quantiser.quantise(x)
    assert q.shape == x.shape and q.dtype == np.int64, (q.shape, q.dtype)
    restored = quantiser.dequantise(q)
    assert restored.shape == x.shape and restored.dtype == np.float64
    bound = (0.5 + dead_zone) * step
    slack = 4 * np.finfo(np.float64).eps * np.abs(x)  # q * step is rounded once
    error = np.abs(x - restored)
    assert np.all(error <= bound + slack), f"{quantiser!r}: error {error.max()} > {bound}"
    assert np.all((q == 0) | (np.sign(q) == np.sign(x))), "a coefficient changed sign"
    assert np.all(q[np.abs(x) < bound - slack] == 0), "a coefficient inside the zero bin was kept"
    np.testing.assert_array_equal(quantiser.quantise(restored), q, err_msg="re-quantising moved a value")
    even = len(x) // 2 * 2
    np.testing.assert_array_equal(quantiser.quantise(x[:even].reshape(-1, 2)), q[:even].reshape(-1, 2))  # any shape
    for bad in (np.nan, np.inf, -np.inf):
        with pytest.raises(ValueError):
            quantiser.quantise(np.array([0.0, bad]))


# --------------------------------------------------------------------------- coefficient coders


def sparse_matrix(rng, rows: int, columns: int, density: float = 0.15, largest: int = 200) -> np.ndarray:
    """Mostly zeros, magnitudes decaying down the rows: what quantised transform coefficients look like."""
    decay = (1.0 + np.arange(rows))[:, None] ** -0.7
    values = np.rint(rng.laplace(scale=largest, size=(rows, columns)) * decay).astype(np.int64)
    return np.where(rng.random((rows, columns)) < density, values, 0)


def coder_sample_matrices() -> list[np.ndarray]:
    """Random sparse matrices and the edge cases a stream must carry: empty, one row, one column,
    magnitudes up to the 2**62 limit, narrow and unsigned input dtypes."""
    rng = np.random.default_rng(5)
    largest = 2**62 - 1
    return [
        sparse_matrix(rng, 120, 12),
        np.zeros((0, 0), np.int64),
        np.zeros((0, 5), np.int64),
        np.zeros((7, 0), np.int64),
        np.zeros((30, 4), np.int64),
        sparse_matrix(rng, 1, 17, density=0.5),
        sparse_matrix(rng, 40, 1, density=0.5),
        np.array([[1]]),
        np.array([[largest, -largest, 0], [0, 1, -(2**40)], [2**31, 0, -1]], np.int64),
        rng.integers(-largest, largest, size=(6, 5), dtype=np.int64),  # every bit length
        rng.integers(-3, 4, size=(50, 6)).astype(np.int8),
        rng.integers(0, 1000, size=(20, 3)).astype(np.uint16),
        sparse_matrix(rng, 300, 30, density=0.05, largest=20),
    ]


def coder_priors(coder, n_slots: int):
    """The priors a coder that `needs_priors` starts from (trained as an archive trains them), else None."""
    if not getattr(coder, "needs_priors", False):
        return None
    from mocapzip.codec.entropy.coefficients import Priors

    rng = np.random.default_rng(6)
    streams = [[sparse_matrix(rng, 80, 8) for _ in range(n_slots)] for _ in range(4)]
    return Priors.decode(Priors.train(streams).encode())  # as a reader gets them: through their bytes


def check_coefficient_coder_round_trip(coder) -> None:
    """Integer matrices come back exactly, as int64, alone or many to a stream; a stream decoded
    against other shapes is refused (readers pass the shapes an archive row declares)."""
    matrices = coder_sample_matrices()
    priors = coder_priors(coder, len(matrices))
    shapes = [m.shape for m in matrices]
    groups = [[m] for m in matrices] + [matrices, matrices[:2], []]
    for group in groups:
        blob = coder.encode(group, priors)
        assert isinstance(blob, bytes)
        assert coder.encode(group, priors) == blob, "encoding is not deterministic"
        for given in ([m.shape for m in group], None):
            decoded = coder.decode(blob, given, priors)
            assert len(decoded) == len(group)
            for out, matrix in zip(decoded, group):
                assert out.dtype == np.int64 and out.shape == matrix.shape, (out.dtype, out.shape, matrix.shape)
                np.testing.assert_array_equal(out, matrix)
    blob = coder.encode(matrices, priors)
    wrong = [(rows + 1, columns) for rows, columns in shapes]
    with pytest.raises(ValueError):
        coder.decode(blob, wrong, priors)
    with pytest.raises(ValueError):
        coder.decode(blob + b"\0", shapes, priors)  # padding is damage, never ignored
    with pytest.raises(ValueError):
        coder.encode([np.zeros((2, 2), np.float64)], priors)  # integers only
    with pytest.raises(ValueError):
        coder.encode([np.array([[2**62]], np.int64)], priors)  # beyond the quantiser's range


def lossless_stream_version(blob: bytes) -> int:
    """The version a lossless channel stream records (first value of its zstd'd channel table)."""
    from mocapzip.codec.entropy.zstd import decode_ints, unpack_blobs

    return int(decode_ints(unpack_blobs(blob)[0])[0])


def check_matrices_equal(decoded, expected) -> None:
    assert len(decoded) == len(expected), (len(decoded), len(expected))
    for out, matrix in zip(decoded, expected):
        assert out.dtype == np.int64 and out.shape == matrix.shape
        np.testing.assert_array_equal(out, matrix)


# --------------------------------------------------------------------------- lossless coders


def assert_bits_equal(actual: np.ndarray, expected: np.ndarray) -> None:
    """float64 arrays equal bit for bit: -0.0 is not 0.0 and NaN equals its own bits."""
    assert actual.dtype == np.float64 and actual.shape == expected.shape, (actual.dtype, actual.shape, expected.shape)
    differ = np.flatnonzero(np.ascontiguousarray(actual).view(np.int64) != np.ascontiguousarray(expected).view(np.int64))
    assert differ.size == 0, f"{differ.size} values differ in their bits, first at flat index {differ[0]}"


def check_lossless_round_trip(coder, values: np.ndarray) -> None:
    """AMC values come back bit for bit, so the text a writer formats from them is the file's."""
    values = np.ascontiguousarray(values, dtype=np.float64)
    blob = coder.encode(values)
    assert isinstance(blob, bytes)
    assert coder.encode(values) == blob, "encoding is not deterministic"
    assert_bits_equal(coder.decode(blob), values)
    # The specials the coder promises too, inside real data: signed zeros, NaN, infinities,
    # binary fractions (no short decimal form), a constant and a duplicated channel.
    special = values.copy()
    special[1, 0], special[2, 1], special[3, 2], special[4, 3] = -0.0, np.nan, np.inf, -np.inf
    special[5, 4], special[6, 5] = 1.0 / 3.0, 5e-324
    special[:, 6] = -0.0
    special[:, 7] = special[:, 8]
    assert_bits_equal(coder.decode(coder.encode(special)), special)
    for shape in ((0, values.shape[1]), (1, values.shape[1]), (values.shape[0], 0)):
        empty = values[: shape[0], : shape[1]]
        assert_bits_equal(coder.decode(coder.encode(empty)), empty)
    with pytest.raises(ValueError):
        coder.decode(blob[:-1])


# --------------------------------------------------------------------------- representations


@lru_cache(maxsize=None)
def load_clip(data: Path, frames: int | None = None) -> tuple[SkeletonModel, Motion]:
    """The contract tests' real clip (09_01, a walk), optionally its first `frames` frames."""
    model = SkeletonModel.from_asf(read_asf(Path(data) / CLIP_ASF))
    motion = read_amc(Path(data) / CLIP_AMC)
    if frames is not None:
        motion = dataclasses.replace(motion, values=motion.values[:frames], frame_numbers=motion.frame_numbers[:frames])
    return model, motion


def encoder_twists(model, motion):
    """The solved bones' twist choice as the encoder makes it (from the clip's own rotations)."""
    from mocapzip.representations.positions import true_twists

    return true_twists(model, motion.values, motion)


def check_representation_round_trip(representation, model: SkeletonModel, motion: Motion) -> None:
    """forward then inverse gives the clip's channels back (a lossless archive of the pose
    matrix would decode to the file), with the twist choice the encoder makes."""
    original = motion.values.copy()
    encoded = representation.forward(model, motion)
    np.testing.assert_array_equal(motion.values, original, err_msg="forward changed the clip")
    assert encoded.poses.ndim == 2 and encoded.poses.shape[0] == motion.n_frames and encoded.poses.dtype == np.float64
    assert np.all(np.isfinite(encoded.poses))
    root_shape = (motion.n_frames, representation.root_width) if representation.root_width else None
    assert (None if encoded.root is None else encoded.root.shape) == root_shape, "root track not as declared"
    encoded.params["twist"] = encoder_twists(model, motion)
    values = representation.inverse(model, encoded, motion)
    assert values.shape == original.shape and values.dtype == np.float64
    np.testing.assert_allclose(values, original, rtol=0, atol=REPRESENTATION_TOLERANCE,
                               err_msg=f"{representation!r}: channels (degrees, cm) not given back")


# --------------------------------------------------------------------------- fixtures


def kind_slug(kind: str) -> str:
    return kind.replace(" ", "_")


def fixture_name(kind: str, codec_id: str, variant: str = "") -> str:
    """tests/golden/stages/<kind>-<id>[-<variant>].npz; the variant names a stream version or config."""
    return "-".join(part for part in (kind_slug(kind), codec_id, variant) if part) + ".npz"


def as_bytes_array(blob: bytes) -> np.ndarray:
    return np.frombuffer(blob, np.uint8).copy()


def save_fixture(path: Path, meta: dict, arrays: dict[str, np.ndarray]) -> None:
    """Write one fixture, never over an existing file: written to a temporary name, then linked
    to its own (os.link fails if the name exists), so a crash leaves no half-written fixture."""
    temporary = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    with open(temporary, "xb") as fh:
        np.savez(fh, meta=np.array(json.dumps(meta, sort_keys=True)), **arrays, allow_pickle=False)
    try:
        os.link(temporary, path)
    finally:
        temporary.unlink()


def load_fixture(path: Path) -> tuple[dict, dict[str, np.ndarray]]:
    """(meta, arrays) of a fixture; no pickles, so a fixture is data and never code."""
    with np.load(path, allow_pickle=False) as npz:
        arrays = {key: npz[key] for key in npz.files}
    return json.loads(str(arrays.pop("meta"))), arrays


def fixture_matrices(arrays: dict, prefix: str = "input") -> list[np.ndarray]:
    """The matrices stored as <prefix>_0, <prefix>_1, ... in order."""
    count = sum(1 for key in arrays if key.startswith(f"{prefix}_") and key[len(prefix) + 1 :].isdigit())
    return [arrays[f"{prefix}_{i}"] for i in range(count)]
