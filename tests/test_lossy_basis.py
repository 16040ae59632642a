"""The stored class basis (`codec.basis.ClassBasis`): exact round trips and reference rows, and the
layouts of formats 1 and 2 (`legacy.streams`)."""

import numpy as np
import pytest

from mocapzip.codec.entropy.coefficients import encode_matrices
from mocapzip.legacy import streams as legacy
from mocapzip.codec.basis import MEAN_STEP_CM, ClassBasis, _reference_rows
from mocapzip.codec.clip_stream import CodedClip
from mocapzip.codec.entropy.zstd import encode_ints


def related_basis(seed=0, groups=10, q=12):
    """Rows in groups of three (x, y, z of a joint), each group a small change from an earlier one."""
    rng = np.random.default_rng(seed)
    rows = [rng.normal(size=(3, q))]
    for _ in range(groups - 1):
        parent = rows[rng.integers(len(rows))]
        rows.append(parent + 0.1 * rng.normal(size=(3, q)))
    components = np.vstack(rows) / np.sqrt(3 * groups)
    steps = np.full(q, 0.002) * (1 + np.arange(q))
    return ClassBasis.quantised(rng.normal(size=3 * groups) * 10, components, steps)


def test_round_trip_is_exact():
    basis = related_basis()
    back = ClassBasis.decode(basis.encode())
    assert np.array_equal(back.components, basis.components) and np.array_equal(back.mean, basis.mean)
    assert np.array_equal(back.steps, basis.steps)


def test_reference_rows_make_related_rows_cheaper():
    basis = related_basis(1)
    ints = np.round(basis.components / basis.steps.astype(np.float64)).astype(np.int64)
    references = _reference_rows(ints)
    assert np.all(references < np.arange(len(ints)))
    assert np.count_nonzero(references[3:] >= 0) > 0.8 * (len(ints) - 3)
    mean_ints = np.round(basis.mean / MEAN_STEP_CM).astype(np.int64)[:, None]
    without = len(encode_matrices([mean_ints, ints]))  # the format-2 layout
    header = 8 + 4 * basis.q
    assert len(basis.encode()) - header < 0.8 * without


def test_format_2_layout_still_decodes():
    basis = related_basis(2)
    ints = np.round(basis.components / basis.steps.astype(np.float64)).astype(np.int64)
    mean_ints = np.round(basis.mean / MEAN_STEP_CM).astype(np.int64)[:, None]
    head = basis.encode()[: 8 + 4 * basis.q]
    back = legacy.class_v2(head + encode_matrices([mean_ints[:, 0:1], ints]))
    assert np.array_equal(back.components, basis.components) and np.array_equal(back.mean, basis.mean)
    with pytest.raises(ValueError, match="shapes"):  # format 4 reads only its own layout
        ClassBasis.decode(head + encode_matrices([mean_ints, ints]))


def test_format_1_layout_still_decodes():
    basis = related_basis(4)
    mean_ints, ints = basis.integers()
    blobs = [encode_ints(mean_ints), encode_ints(ints)]
    head = basis.encode()[: 8 + 4 * basis.q]
    back = legacy.class_v1(head + b"".join(len(b).to_bytes(4, "little") + b for b in blobs))
    assert np.array_equal(back.components, basis.components) and np.array_equal(back.mean, basis.mean)


def test_reference_to_a_later_row_is_refused():
    basis = related_basis(3)
    m, q = basis.components.shape
    head = basis.encode()[: 8 + 4 * q]
    offsets = np.zeros((m, 1), np.int64)
    offsets[2] = 5  # row 2 cannot refer to row -3
    blob = head + encode_matrices([np.zeros((m, 1), np.int64), offsets, np.zeros((m, q), np.int64)])
    with pytest.raises(ValueError, match="does not come before"):
        ClassBasis.decode(blob)
    with pytest.raises(ValueError, match="shapes"):
        ClassBasis.decode(head + encode_matrices([np.zeros((m, 1), np.int64)]))


def test_shapes_are_checked_before_decoding():
    """A header naming other shapes is refused before a matrix of that size is decoded."""
    basis = related_basis(4)
    m, q = basis.components.shape
    head = basis.encode()[: 8 + 4 * basis.q]
    other = encode_matrices([np.zeros((m, 1), np.int64), np.zeros((m, 1), np.int64), np.zeros((m + 1, q), np.int64)])
    with pytest.raises(ValueError, match="shapes"):
        ClassBasis.decode(head + other)


def test_unknown_coder_is_refused_not_taken_for_zstd():
    coded = CodedClip(1.0, np.zeros((3, 2), np.int64), 1.0, None)
    for call in (lambda: coded.payload("auto"), lambda: CodedClip.from_payload(coded.payload(), "auto")):
        with pytest.raises(ValueError, match="unknown coefficient coder"):
            call()


def test_format_1_coder_is_read_never_written():
    coded = CodedClip(1.0, np.zeros((3, 2), np.int64), 1.0, None)
    with pytest.raises(ValueError, match="read only"):
        coded.payload("zstd")
    blob = (1.0).hex() and b"\x00" * 16 + bytes([1]) + len(encode_ints(coded.pose_ints)).to_bytes(4, "little") \
        + encode_ints(coded.pose_ints)
    back = legacy.clip_v1(blob, [(3, 2), (3, 4)])
    assert np.array_equal(back.pose_ints, coded.pose_ints) and back.root_ints is None
