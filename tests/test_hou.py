"""Hou et al. 2015 tailored transform coding (the `mcz bench --codec hou` baseline) on a real clip."""

from __future__ import annotations

import numpy as np
import pytest

from mocapzip.bench.baselines import hou as hou
from mocapzip.codec.entropy.zstd import decode_ints, unpack_blobs
from mocapzip.formats.amc import read_amc
from mocapzip.formats.asf import read_asf
from mocapzip.motion.kinematics import forward
from mocapzip.motion.skeleton import SkeletonModel


@pytest.fixture(scope="module")
def positions(shared_data):
    """Joint positions (cm) of the first 300 frames of CMU 07_01 (a walk): (300, 31, 3)."""
    model = SkeletonModel.from_asf(read_asf(shared_data / "cmu" / "07" / "07.asf"))
    motion = read_amc(shared_data / "cmu" / "07" / "07_01.amc")
    return forward(model, motion.values[:300], motion).positions


def test_paper_formulas():
    # eq. 12: r = 0.1 ceil(L / 50); l = r k
    assert hou.ratio_r(50) == pytest.approx(0.1)
    assert hou.ratio_r(51) == pytest.approx(0.2)
    assert hou.ratio_r(280) == pytest.approx(0.6)
    assert hou.dct_count(280, 40) == 24
    assert hou.dct_count(5, 93) == 5  # never more coefficients than frames (0.1 x 93 would be 9)
    assert hou.dct_count(50, 1) == 1  # at least one
    # eq. 13: Q = 0 for k <= 30, ceil((k - 30) / 10) above
    assert [hou.paper_q(k) for k in (15, 30, 31, 40, 41, 93)] == [0, 0, 1, 1, 2, 7]


def test_matrix_layout_is_the_papers(positions):
    m = hou.to_matrix(positions)
    n = positions.shape[1]
    assert m.shape == (3 * n, len(positions))
    assert np.array_equal(m[0], positions[:, 0, 0])  # x of joint 1
    assert np.array_equal(m[n + 2], positions[:, 2, 1])  # y of joint 3
    assert np.array_equal(m[2 * n + n - 1], positions[:, n - 1, 2])  # z of joint n
    assert np.array_equal(hou.from_matrix(m), positions)


def test_round_trip_matches_the_stream(positions):
    params = hou.HouParams(L=120, k=20, Q=0)  # 300 frames: clips of 120, 120 and 60 frames
    blob = hou.encode(positions, params)
    assert blob[:4] == hou.MAGIC
    decoded = hou.decode(blob)
    assert decoded.shape == positions.shape
    # the stream holds a 16-bit basis (3n x k) and the coefficients of each clip
    blobs = unpack_blobs(blob[hou.HEADER_SIZE:])
    basis = decode_ints(blobs[0])
    assert basis.shape == (93, 20) and basis.dtype == np.int16
    assert decode_ints(blobs[1]).shape == (2, 20, hou.dct_count(120, 20))  # the two full clips
    assert decode_ints(blobs[2]).shape == (20, hou.dct_count(60, 20))  # the short last clip
    b = basis / hou.BASIS_LIMIT
    assert np.allclose(b.T @ b, np.eye(20), atol=1e-3)  # orthonormal up to 16-bit rounding
    # encoding is deterministic, and the error is a few cm at most for a walk at k = 20
    assert hou.encode(positions, params) == blob
    err = hou.errors(positions, decoded)
    assert 0 < err["mean_error_cm"] < 3
    assert err["mean_error_cm"] <= err["p99_error_cm"] <= err["max_error_cm"]


def test_more_coefficients_less_error_more_bytes(positions):
    coarse = hou.encode(positions, hou.HouParams(L=150, k=8, Q=0))
    fine = hou.encode(positions, hou.HouParams(L=150, k=40, Q=3))
    e_coarse = hou.errors(positions, hou.decode(coarse))["mean_error_cm"]
    e_fine = hou.errors(positions, hou.decode(fine))["mean_error_cm"]
    assert e_fine < e_coarse / 3
    assert len(fine) > len(coarse)


GRID = {"grid_l": (100, 300), "grid_k": (10, 20, 30), "grid_q": (-2, 0, 2)}


@pytest.fixture(scope="module")
def full_sweep(positions):
    return hou.sweep(positions, **GRID)


def test_sweep_reports_real_bytes_and_errors(positions, full_sweep):
    points = full_sweep
    assert len(points) == 2 * 3 * 3
    for p in points[::5]:
        blob = hou.encode(positions, hou.HouParams(p["L"], p["k"], p["Q"]))
        assert len(blob) == p["bytes"]
        assert hou.errors(positions, hou.decode(blob))["mean_error_cm"] == pytest.approx(p["mean_error_cm"])
    for target in (2.0, 1.0):
        best = hou.best(points, target)
        assert best is not None and best["mean_error_cm"] <= target
        assert best["bytes"] == min(p["bytes"] for p in points if p["mean_error_cm"] <= target)
    assert hou.best(points, 1e-6) is None


def test_sweep_with_targets_finds_the_same_best(positions, full_sweep):
    full = full_sweep
    pruned = hou.sweep(positions, targets=[2.0, 1.0], **GRID)
    assert len(pruned) < len(full)
    for target in (2.0, 1.0):
        assert hou.best(pruned, target) == hou.best(full, target)


def test_shared_basis_streams_decode(positions):
    halves = [positions[:170], positions[170:]]  # two "sequences" sharing one basis
    found = hou.sweep_shared(halves, targets=[2.0], grid_l=(100, 200), grid_k=(20, 30), grid_q=(-2, 0))
    choice = found[2.0]
    assert choice is not None and choice["bytes"] == choice["basis_bytes"] + sum(s["bytes"] for s in choice["sequences"])
    basis_blob, streams = hou.encode_shared(halves, choice["L"], choice["k"], [s["Q"] for s in choice["sequences"]])
    assert len(basis_blob) == choice["basis_bytes"]
    basis = hou.decode_basis(basis_blob)
    for seq, stream, reported in zip(halves, streams, choice["sequences"]):
        assert len(stream) == reported["bytes"]
        err = hou.errors(seq, hou.decode_clip(stream, basis))["mean_error_cm"]
        assert err == pytest.approx(reported["mean_error_cm"]) and err <= 2.0
