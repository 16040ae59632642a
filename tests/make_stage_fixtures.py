"""Write the frozen per-stage fixtures tests/golden/stages/*.npz, one per stage id (and per stream
version, where a stage's stream carries one), which tests/test_stage_contracts.py decodes and
re-encodes.

Run by hand, from the repository root, after registering a stage or adding a stream version:

    .venv/bin/python tests/make_stage_fixtures.py

It writes the fixtures that are missing and refuses to touch one that exists: like the golden
archives (tests/make_golden_archives.py), each fixture stays for good, so every future decoder is
tested against what an encoder wrote once, and any change of an encoder's output fails a test.

Fixed inputs: seeded synthetic integers and curves for the coefficient coders, transforms and
the quantiser; the first 60 frames of the real clip cmu/09/09_01 for the representations and the
lossless coder. A stream no encoder writes any more is built by hand as its writer laid it out:
format 1's coefficient coder "zstd" and the lossless coder's stream version 1.
"""

import struct
import sys

from conftest import DATA  # also one BLAS thread, as under pytest: the arrays are computed alike

import numpy as np
import scipy.fft

from common import (CLIP_AMC, CLIP_ASF, FIXTURE_FRAMES, STAGE_FIXTURES, as_bytes_array, assert_bits_equal,
                    check_matrices_equal, encoder_twists, fixture_name, load_clip, lossless_stream_version,
                    save_fixture)
from mocapzip.codec import lossless
from mocapzip.codec.entropy import zstd as entropy
from mocapzip.codec.entropy.coefficients import Priors, matrix_stream_version
from mocapzip.representations.base import Encoded
from mocapzip.representations.positions import flip_ranges, flips_from_ranges
from mocapzip.stages import KINDS, get_stage, stage_classes

# Configs other than a stage's defaults, where the defaults would leave a behaviour unpinned.
CONFIGS = {
    ("quantiser", "uniform"): {"id": "uniform", "step": 0.25, "dead_zone": 0.125},  # a dead zone, binary-exact
}


def meta_for(stage, version=None, encoder_golden=True, **more) -> dict:
    return {"kind": stage.kind, "codec_id": stage.codec_id, "config": stage.get_config(), "version": version,
            "encoder_golden": encoder_golden, **more}


def default_stage(kind, codec_id, cls):
    config = CONFIGS.get((kind, codec_id))
    return get_stage(kind, config) if config else cls()


# --------------------------------------------------------------------------- transforms, quantiser


def transform_fixtures(codec_id, cls):
    stage = default_stage("transform", codec_id, cls)
    rng = np.random.default_rng(21)
    curves = np.cumsum(rng.normal(size=(101, 4)), axis=0)  # odd length: DWT's odd sample too
    coefs = stage.forward(curves)
    decoded = stage.inverse(coefs, len(curves))
    np.testing.assert_allclose(decoded, curves, rtol=0, atol=1e-12 * np.abs(curves).max())
    meta = meta_for(stage, input="np.cumsum(np.random.default_rng(21).normal(size=(101, 4)), axis=0)")
    yield "", meta, {"input": curves, "encoded": coefs, "decoded": decoded}


def quantiser_fixtures(codec_id, cls):
    stage = default_stage("quantiser", codec_id, cls)
    rng = np.random.default_rng(22)
    values = rng.normal(scale=2.0, size=(64, 5))
    step, dead_zone = getattr(stage, "step", 1.0), getattr(stage, "dead_zone", 0.0)
    edges = (np.array([1.0, -2.0]) - np.sign([1.0, -2.0]) * (0.5 - dead_zone)) * step  # where 1 and -2 start
    values[0] = [0.0, -0.0, *edges, np.nextafter(edges[0], 0.0)]  # on bin edges, one ulp below one
    ints = stage.quantise(values)
    meta = meta_for(stage, input="np.random.default_rng(22).normal(scale=2, size=(64, 5)), row 0: 0, -0, bin edges")
    yield "", meta, {"input": values, "encoded": ints, "decoded": stage.dequantise(ints)}


# --------------------------------------------------------------------------- coefficient coders


def quantised_dct(rng, n_frames, n_curves, step):
    """Quantised DCT coefficients of smooth random curves: sparse, large at low frequencies."""
    curves = np.cumsum(np.cumsum(rng.normal(size=(n_frames, n_curves)), axis=0), axis=0)
    return np.rint(scipy.fft.dct(curves, norm="ortho", axis=0) / step).astype(np.int64)


def clip_matrices(rng):
    """A clip's pose and root coefficient matrices (format 1 held one or two a stream)."""
    return [quantised_dct(rng, 64, 6, 20.0), quantised_dct(rng, 64, 4, 5.0)]


def format1_zstd_stream(matrices) -> bytes:
    """Format 1's clip matrices after its two f64 steps (`legacy.streams.ZstdCoder`): u8 count, then
    per matrix a u32 little-endian length and `encode_sparse` of it, as the format-1 writer
    (git e152d64, mocapzip/lossy.py CodedClip.payload) laid them out. encode_sparse is
    encode_ints or, when smaller, its bitmap layout: the pose matrix here takes the bitmap."""
    blobs = [entropy.encode_sparse(matrix) for matrix in matrices]
    return bytes([len(blobs)]) + b"".join(struct.pack("<I", len(blob)) + blob for blob in blobs)


HAND_BUILT_COEFFICIENT_STREAMS = {"zstd": format1_zstd_stream}


def coefficient_coder_fixtures(codec_id, cls):
    stage = default_stage("coefficient coder", codec_id, cls)
    matrices = clip_matrices(np.random.default_rng(31))
    arrays = {f"input_{i}": matrix for i, matrix in enumerate(matrices)}
    description = "clip_matrices(np.random.default_rng(31)) in tests/make_stage_fixtures.py"
    priors = None
    if getattr(stage, "needs_priors", False):
        train_rng = np.random.default_rng(32)
        streams = [clip_matrices(train_rng) for _ in range(3)]
        priors = Priors.train(streams)
        arrays["priors"] = as_bytes_array(priors.encode())
        for i, stream in enumerate(streams):
            arrays.update({f"train{i}_{slot}": matrix for slot, matrix in enumerate(stream)})
    if getattr(stage, "decode_only", False):
        if codec_id not in HAND_BUILT_COEFFICIENT_STREAMS:
            sys.exit(f"coefficient coder {codec_id!r} is decode only: add its stream builder to "
                     "HAND_BUILT_COEFFICIENT_STREAMS in tests/make_stage_fixtures.py")
        blob, version, golden = HAND_BUILT_COEFFICIENT_STREAMS[codec_id](matrices), None, False
    else:
        blob = stage.encode(matrices, priors)
        version, golden = matrix_stream_version(blob), True
    check_matrices_equal(stage.decode(blob, [m.shape for m in matrices], priors), matrices)
    arrays["encoded"] = as_bytes_array(blob)
    yield (f"v{version}" if version is not None else "format1"), meta_for(stage, version, golden, input=description), arrays


# --------------------------------------------------------------------------- lossless coder


def lossless_v1_stream(values) -> bytes:
    """Lossless stream version 1 (formats 1 and 2), as its writer laid it out (git e152d64^,
    mocapzip/codec/lossless.py encode_channels): the same channel split as version 2, but each
    channel predicted by its own best order, no links, residuals and digit groups all as
    `encode_ints`. Checked once to give, byte for byte, that writer's own 50-frame stream
    (tests/golden/lossless_v1.bin, removed in git f2699a6) from the values it decodes to."""
    L = lossless
    values = np.ascontiguousarray(values, dtype=np.float64)
    n_frames, n_channels = values.shape
    bits = values.view(np.int64)
    table = np.zeros((n_channels, 4), np.int64)
    first_seen, columns = {}, []
    for column in range(n_channels):
        column_bits = bits[:, column]
        if n_frames and np.all(column_bits == column_bits[0]):
            table[column] = (L._CONSTANT, column_bits[0], 0, 0)
            continue
        key = column_bits.tobytes()
        if key in first_seen:
            table[column] = (L._DUPLICATE, first_seen[key], 0, 0)
            continue
        first_seen[key] = column
        columns.append(column)
    needed, shortest_unit = L._shortest_decimal(values[:, columns])
    channels = [L._encode_decimal(values[:, column], needed[:, i], shortest_unit[:, i]) for i, column in enumerate(columns)]
    for column, channel in zip(columns, channels):
        table[column] = (L._DECIMAL, channel.sig_digits, channel.coarse_exponent, channel.order)
    shape = (len(channels), n_frames)

    def stacked(field, dtype=np.int64):
        return np.array([getattr(channel, field) for channel in channels], dtype).reshape(shape)

    residuals = np.array([L._difference(channel.coarse, channel.order) for channel in channels], np.int64).reshape(shape)
    n_below, digits, coarse = stacked("n_below"), stacked("digits"), stacked("coarse")
    exceptions, negative_zero = stacked("exception", bool), stacked("negative_zero", bool)
    exception_positions = np.flatnonzero(exceptions)
    meta = np.concatenate([[1, n_frames, n_channels], table.ravel()])
    sections = [
        entropy.encode_ints(meta),
        entropy.encode_ints(residuals.ravel()),
        entropy.encode_ints(np.diff(exception_positions, prepend=0)),
        entropy.encode_ints(bits[:, columns].T[exceptions]),
        entropy.encode_bytes(np.packbits(negative_zero[(coarse == 0) & ~exceptions]).tobytes()),
    ]
    for n in range(1, n_below.max(initial=0) + 1):
        group = n_below == n
        if group.any():
            sections.append(entropy.encode_ints(digits[group]))
    return entropy.pack_blobs(sections)


# Stream versions the lossless coders decode but no longer write: {codec id: {version: builder}}.
HAND_BUILT_LOSSLESS_STREAMS = {"decimal": {1: lossless_v1_stream}}


def lossless_coder_fixtures(codec_id, cls):
    stage = default_stage("lossless coder", codec_id, cls)
    _, motion = load_clip(DATA, FIXTURE_FRAMES)
    values = motion.values
    clip = {"asf": CLIP_ASF, "amc": CLIP_AMC, "frames": FIXTURE_FRAMES}
    streams = [(stage.encode(values), True)]
    streams += [(build(values), False) for build in HAND_BUILT_LOSSLESS_STREAMS.get(codec_id, {}).values()]
    for blob, golden in streams:
        assert_bits_equal(stage.decode(blob), values)
        version = lossless_stream_version(blob)
        meta = meta_for(stage, version, golden, input="the first 60 frames of the real clip", clip=clip)
        yield f"v{version}", meta, {"input": values, "encoded": as_bytes_array(blob)}


# --------------------------------------------------------------------------- representations


def representation_fixtures(codec_id, cls):
    model, motion = load_clip(DATA, FIXTURE_FRAMES)
    clip = {"asf": CLIP_ASF, "amc": CLIP_AMC, "frames": FIXTURE_FRAMES}
    default = cls().get_config()
    flags = (False, True) if "axes_from_positions" in default else (None,)
    for flag in flags:
        config = default if flag is None else {**default, "axes_from_positions": flag}
        stage = get_stage("representation", config)
        encoded = stage.forward(model, motion)
        params = dict(encoded.params)
        encoded.params["twist"] = twist = encoder_twists(model, motion)
        stage.inverse(model, encoded, motion)  # records the flips the encoder's twist choice makes
        ranges = flip_ranges(twist.flips, model)
        decoder_params = {**params, "twist": flips_from_ranges(ranges, model, motion.n_frames)}  # as a reader has them
        decoded = stage.inverse(model, Encoded(encoded.poses, encoded.root, decoder_params), motion)
        np.testing.assert_allclose(decoded, motion.values, rtol=0, atol=1e-6)
        arrays = {"input": motion.values, "encoded_poses": encoded.poses, "decoded": decoded}
        if encoded.root is not None:
            arrays["encoded_root"] = encoded.root
        for key, value in params.items():
            arrays[f"param_{key}"] = np.asarray(value, np.float64)
        meta = meta_for(stage, input="the first 60 frames of the real clip", clip=clip, twist_ranges=ranges)
        yield ("axes_from_positions" if flag else ""), meta, arrays


BUILDERS = {
    "representation": representation_fixtures,
    "transform": transform_fixtures,
    "quantiser": quantiser_fixtures,
    "coefficient coder": coefficient_coder_fixtures,
    "lossless coder": lossless_coder_fixtures,
}

if __name__ == "__main__":
    STAGE_FIXTURES.mkdir(parents=True, exist_ok=True)
    for kind in KINDS:
        for codec_id, cls in stage_classes(kind).items():
            for variant, meta, arrays in BUILDERS[kind](codec_id, cls):
                path = STAGE_FIXTURES / fixture_name(kind, codec_id, variant)
                if path.exists():
                    print(f"kept {path.name}: fixtures are never regenerated")
                    continue
                save_fixture(path, meta, arrays)
                print(f"wrote {path.name}: {path.stat().st_size} bytes")
