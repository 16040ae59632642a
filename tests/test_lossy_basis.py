"""The stored class basis (`lossy.ClassBasis`): exact round trips and reference rows."""

import numpy as np
import pytest

from mocapzip.codec.coefficients import encode_matrices
from mocapzip.lossy import MEAN_STEP_CM, ClassBasis, CodedClip, _reference_rows


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


@pytest.mark.parametrize("coder", ["primed", "context", "zstd"])
def test_round_trip_is_exact(coder):
    basis = related_basis()
    back = ClassBasis.decode(basis.encode(coder), coder)
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
    back = ClassBasis.decode(head + encode_matrices([mean_ints, ints]))
    assert np.array_equal(back.components, basis.components)


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
