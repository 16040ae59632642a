"""Hou et al. 2015, "Human motion capture data tailored transform coding", section IV.

A baseline for `mcz bench --codec hou`, never the product's codec. It codes joint
*positions* (no rotations, no AMC channels), so its error is measured on joint
positions directly: there is no AMC file to write back.

The algorithm, as in the paper (seed 001, sections IV and VI-A):

* The sequence is the matrix M (3n x f): rows x_1..x_n, y_1..y_n, z_1..z_n of the
  n joint positions (cm), one column per frame. It is cut into clips of L frames
  (the paper crops f to a multiple of L; frames are never dropped here, so the
  last clip may be shorter, L_N = f mod L, and gets its own DCT length).
* Right basis: the truncated orthonormal DCT-II of each clip, l_i = r k
  coefficients with r = 0.1 ceil(L_i / 50) (eq. 12), rounded to the nearest
  integer and kept within 1..L_i.
* Left basis: ONE data-dependent orthonormal B (3n x k) for the whole sequence,
  the k leading eigenvectors of C = sum_i M_i D_i D_i^T M_i^T (eqs. 4-6); no mean
  is subtracted (the paper subtracts none; the DC term of the DCT carries it).
* B is stored with 16 bits per element (round(b * 32767)); the coefficients
  S_i = B^T M_i D_i keep Q fractional bits: round(s * 2^Q). The paper's Q >= 0;
  `sweep` also tries negative Q (steps of 2, 4, 8 cm-units), a generalisation
  that can only help the baseline at large errors.
* Lossless coding: the paper leaves the coder open ("other advanced lossless
  entropy coding schemes can also be applied"); we use the project's own integer
  coder (`codec.entropy.encode_ints`: zigzag, byte planes or bit lengths, zstd -19),
  the same one mocapzip's coefficients go through, so the coder is not what differs.
* Decoder: M_i ~ B S_i D_i^T.

Stream layout (`encode` / `decode`): an 18-byte header `<4sHIHHhH` (magic b"HOU1",
3n, f, L, k, Q, reserved) then `pack_blobs` of [B as int16, the full clips'
coefficients (N, k, l), the last short clip's coefficients (k, l_N) if any].
"""

from __future__ import annotations

import math
import struct
from dataclasses import dataclass

import numpy as np
import scipy.fft

from mocapzip.codec.entropy.zstd import decode_ints, encode_ints, pack_blobs, unpack_blobs

MAGIC = b"HOU1"
_HEADER = struct.Struct("<4sHIHHhH")
HEADER_SIZE = _HEADER.size  # 18
BASIS_LIMIT = 2**15 - 1  # 16-bit basis elements: b ~ round(b * 32767) / 32767

# The parameter grid `mcz bench --codec hou` searches per clip (fewest bytes that meet
# the error). The paper samples k from 15 to 65 (Fig. 8), finds L >= 350 brings
# little more (VI-B1) and uses Q = 0..7 (eq. 13); the grid is wider on every side.
GRID_L = (120, 240, 360, 480)
GRID_K = (3, 4, 6, 8, 10, 12, 15, 18, 21, 25, 30, 35, 40, 50, 60)
GRID_Q = tuple(range(-7, 6))


@dataclass(frozen=True, order=True)
class HouParams:
    L: int  # clip length in frames
    k: int  # size of the left (data-dependent) basis
    Q: int  # fractional bits kept of each coefficient (negative: coarser than integers)

    def as_dict(self) -> dict:
        return {"L": self.L, "k": self.k, "Q": self.Q}


def ratio_r(length: int) -> float:
    """Eq. 12: r = l / k = 0.1 ceil(L / 50)."""
    return 0.1 * math.ceil(length / 50)


def dct_count(length: int, k: int) -> int:
    """l = r k DCT coefficients for a clip of `length` frames (at least 1, at most `length`)."""
    return int(min(length, max(1, round(ratio_r(length) * k))))


def paper_q(k: int) -> int:
    """Eq. 13, the paper's automatic Q: 0 for k <= 30, else ceil((k - 30) / 10)."""
    return 0 if k <= 30 else math.ceil((k - 30) / 10)


def to_matrix(positions: np.ndarray) -> np.ndarray:
    """(f, n, 3) joint positions -> M (3n x f): x rows, then y rows, then z rows."""
    positions = np.asarray(positions, dtype=np.float64)
    f, n, _ = positions.shape
    return np.ascontiguousarray(positions.transpose(2, 1, 0).reshape(3 * n, f))


def from_matrix(matrix: np.ndarray) -> np.ndarray:
    """Inverse of `to_matrix`."""
    rows, f = matrix.shape
    return np.ascontiguousarray(matrix.reshape(3, rows // 3, f).transpose(2, 1, 0))


def segments(n_frames: int, length: int) -> list[tuple[int, int]]:
    """Clips of `length` frames; the last is shorter when n_frames is not a multiple."""
    return [(a, min(a + length, n_frames)) for a in range(0, n_frames, length)]


class _Sequence:
    """One sequence's DCT coefficients per clip length, so a parameter sweep reuses them."""

    def __init__(self, positions: np.ndarray):
        self.positions = np.asarray(positions, dtype=np.float64)
        self.matrix = to_matrix(self.positions)
        self._dct: dict[int, list[np.ndarray]] = {}

    @property
    def rows(self) -> int:
        return self.matrix.shape[0]

    @property
    def n_frames(self) -> int:
        return self.matrix.shape[1]

    def coefficients(self, length: int) -> list[np.ndarray]:
        """Full orthonormal DCT-II of each clip's rows: M_i D (3n x L_i)."""
        if length not in self._dct:
            n_full = self.n_frames // length
            block = self.matrix[:, : n_full * length].reshape(self.rows, n_full, length)
            block = scipy.fft.dct(block, type=2, norm="ortho", axis=2)
            parts = [block[:, i] for i in range(n_full)]
            if self.n_frames % length:
                parts.append(scipy.fft.dct(self.matrix[:, n_full * length :], type=2, norm="ortho", axis=1))
            self._dct[length] = parts
        return self._dct[length]

    def basis(self, length: int, k: int) -> np.ndarray:
        """The k leading eigenvectors of C = sum_i (M_i D_i)(M_i D_i)^T, quantised to 16 bits (as ints)."""
        k = min(k, self.rows)
        c = np.zeros((self.rows, self.rows))
        for coef in self.coefficients(length):
            part = coef[:, : dct_count(coef.shape[1], k)]
            c += part @ part.T
        values, vectors = np.linalg.eigh(c)
        b = vectors[:, ::-1][:, :k]
        b = b * np.where(b[np.abs(b).argmax(axis=0), np.arange(k)] < 0, -1.0, 1.0)  # a fixed sign per vector
        return np.round(b * BASIS_LIMIT).astype(np.int16)

    def project(self, length: int, basis_ints: np.ndarray) -> list[np.ndarray]:
        """S_i = B^T M_i D_i with the stored (quantised) B, truncated to l_i coefficients."""
        b = basis_ints.astype(np.float64) / BASIS_LIMIT
        k = b.shape[1]
        return [b.T @ coef[:, : dct_count(coef.shape[1], k)] for coef in self.coefficients(length)]


def _reconstruct(basis_ints: np.ndarray, coefficient_ints: list[np.ndarray], q: int, lengths: list[int]) -> np.ndarray:
    """Positions (f, n, 3) from the stored integers: M_i = B S_i D_i^T."""
    b = basis_ints.astype(np.float64) / BASIS_LIMIT
    return from_matrix(_synthesise(b, [c.astype(np.float64) * 2.0 ** (-q) for c in coefficient_ints], lengths))


def _synthesise(b: np.ndarray, coefficients: list[np.ndarray], lengths: list[int]) -> np.ndarray:
    """M (3n x f) = [B S_1 D_1^T, B S_2 D_2^T, ...]; the full-length clips in one batched inverse DCT."""
    rows = b.shape[0]
    out = np.empty((rows, sum(lengths)))
    n_full = sum(1 for n in lengths if n == lengths[0])
    if n_full:
        s = np.stack(coefficients[:n_full])  # (N, k, l)
        full = np.zeros((n_full, rows, lengths[0]))
        full[:, :, : s.shape[2]] = np.einsum("rk,nkl->nrl", b, s)
        block = scipy.fft.idct(full, type=2, norm="ortho", axis=2)  # (N, 3n, L)
        out[:, : n_full * lengths[0]] = block.transpose(1, 0, 2).reshape(rows, -1)
    start = n_full * lengths[0]
    for s, n in zip(coefficients[n_full:], lengths[n_full:]):
        full = np.zeros((rows, n))
        full[:, : s.shape[1]] = b @ s
        out[:, start : start + n] = scipy.fft.idct(full, type=2, norm="ortho", axis=1)
        start += n
    return out


def _mean_error(matrix: np.ndarray, approx: np.ndarray) -> float:
    """Mean joint distance (cm) between two 3n x f matrices, without reshaping."""
    n = matrix.shape[0] // 3
    d = (approx - matrix) ** 2
    return float(np.sqrt(d[:n] + d[n : 2 * n] + d[2 * n :]).mean())


def _quantise(coefficients: list[np.ndarray], q: int) -> list[np.ndarray]:
    return [np.round(s * 2.0**q).astype(np.int64) for s in coefficients]


def _pack(rows: int, n_frames: int, params: HouParams, basis_ints, coefficient_ints) -> bytes:
    full = [c for c in coefficient_ints if c.shape == coefficient_ints[0].shape]
    if len(coefficient_ints) > 1 and coefficient_ints[-1].shape != coefficient_ints[0].shape:
        blobs = [encode_ints(basis_ints), encode_ints(np.stack(full)), encode_ints(coefficient_ints[-1])]
    else:
        blobs = [encode_ints(basis_ints), encode_ints(np.stack(coefficient_ints))]
    header = _HEADER.pack(MAGIC, rows, n_frames, params.L, basis_ints.shape[1], params.Q, 0)
    return header + pack_blobs(blobs)


def encode(positions: np.ndarray, params: HouParams) -> bytes:
    """Code a sequence of joint positions (f, n, 3) in cm with parameters L, k, Q."""
    seq = _Sequence(positions)
    if seq.n_frames == 0:
        raise ValueError("cannot code an empty sequence")
    basis_ints = seq.basis(params.L, params.k)
    ints = _quantise(seq.project(params.L, basis_ints), params.Q)
    return _pack(seq.rows, seq.n_frames, params, basis_ints, ints)


def decode(blob: bytes) -> np.ndarray:
    """Joint positions (f, n, 3) in cm from `encode`'s bytes."""
    magic, rows, n_frames, length, k, q, _ = _HEADER.unpack_from(blob, 0)
    if magic != MAGIC:
        raise ValueError("not a Hou et al. stream (bad magic)")
    blobs = unpack_blobs(blob[_HEADER.size:])
    basis_ints = decode_ints(blobs[0])
    if basis_ints.shape != (rows, k):
        raise ValueError(f"basis has shape {basis_ints.shape}, expected {(rows, k)}")
    coefficient_ints = list(decode_ints(blobs[1]))
    if len(blobs) > 2:
        coefficient_ints.append(decode_ints(blobs[2]))
    lengths = [b - a for a, b in segments(n_frames, length)]
    if len(lengths) != len(coefficient_ints):
        raise ValueError("clip count does not match the header")
    return _reconstruct(basis_ints, coefficient_ints, q, lengths)


def errors(original: np.ndarray, decoded: np.ndarray) -> dict:
    """Mean, 99th-percentile and max joint distance (cm), as the rest of the bench reports them."""
    d = np.linalg.norm(np.asarray(decoded) - np.asarray(original), axis=-1)
    return {"mean_error_cm": float(d.mean()), "p99_error_cm": float(np.percentile(d, 99)),
            "max_error_cm": float(d.max())}


def sweep(positions: np.ndarray, targets=None, grid_l=GRID_L, grid_k=GRID_K, grid_q=GRID_Q) -> list[dict]:
    """Evaluate the parameter grid on one sequence; every point's bytes are real encoded bytes.

    Returns one dict per encoded point: L, k, Q, bytes, mean/p99/max error (cm).
    With `targets` (mean errors in cm), only the points that can be a best choice are
    encoded: for each (L, k) and target, the coarsest Q that meets the target (a finer Q
    only adds bytes); a k whose unquantised error already misses every target is skipped.
    Without targets, every point is encoded (a full ratio-distortion cloud).
    """
    seq = _Sequence(positions)
    n_rows = seq.rows
    points = []
    lengths_seen = set()
    for length in grid_l:
        length = min(length, seq.n_frames)
        if length in lengths_seen:
            continue
        lengths_seen.add(length)
        lengths = [b - a for a, b in segments(seq.n_frames, length)]
        for k in sorted({min(k, n_rows) for k in grid_k}):
            basis_ints = seq.basis(length, k)
            b = basis_ints.astype(np.float64) / BASIS_LIMIT
            coefficients = seq.project(length, basis_ints)
            if targets is not None and _mean_error(seq.matrix, _synthesise(b, coefficients, lengths)) > max(targets):
                continue  # truncation alone misses every target: no Q can help
            evaluated = {}
            for q in sorted(grid_q):  # coarse to fine
                ints = _quantise(coefficients, q)
                approx = _synthesise(b, [i * 2.0 ** (-q) for i in ints], lengths)
                evaluated[q] = (ints, _mean_error(seq.matrix, approx))
                if targets is not None and evaluated[q][1] <= min(targets):
                    break
            if targets is None:
                chosen = set(evaluated)
            else:
                chosen = {min(q for q, (_, e) in evaluated.items() if e <= t)
                          for t in targets if any(e <= t for _, e in evaluated.values())}
            for q in sorted(chosen):
                ints = evaluated[q][0]
                params = HouParams(length, k, q)
                size = len(_pack(n_rows, seq.n_frames, params, basis_ints, ints))
                decoded = _reconstruct(basis_ints, ints, q, lengths)
                points.append({**params.as_dict(), "bytes": size, **errors(seq.positions, decoded)})
    return points


# ----------------------------------------------------------------------------- one basis for many sequences
#
# Section V of the paper codes a database with K shared bases; with K = 1 per group (we use one
# group per subject, like mcz's default classes) every sequence of the group is projected on the
# same B. L and k are then shared by the group, Q stays per sequence (the paper's Q_i). Streams:
# one basis stream (header `<4sHH`: b"HOUB", 3n, k; then B as int16) and one stream per sequence
# (header `<4sIHh`: b"HOUC", f, L, Q; then pack_blobs of the clips' coefficients as in `encode`).

_BASIS_HEADER = struct.Struct("<4sHH")
_CLIP_HEADER = struct.Struct("<4sIHh")


def encode_basis(basis_ints: np.ndarray) -> bytes:
    return _BASIS_HEADER.pack(b"HOUB", *basis_ints.shape) + encode_ints(basis_ints)


def decode_basis(blob: bytes) -> np.ndarray:
    magic, rows, k = _BASIS_HEADER.unpack_from(blob, 0)
    if magic != b"HOUB":
        raise ValueError("not a Hou et al. basis stream")
    basis = decode_ints(blob[_BASIS_HEADER.size:])
    if basis.shape != (rows, k):
        raise ValueError(f"basis has shape {basis.shape}, expected {(rows, k)}")
    return basis


def _clip_stream(n_frames: int, length: int, q: int, coefficient_ints: list[np.ndarray]) -> bytes:
    full = [c for c in coefficient_ints if c.shape == coefficient_ints[0].shape]
    blobs = [encode_ints(np.stack(full))]
    if len(full) < len(coefficient_ints):
        blobs.append(encode_ints(coefficient_ints[-1]))
    return _CLIP_HEADER.pack(b"HOUC", n_frames, length, q) + pack_blobs(blobs)


def decode_clip(blob: bytes, basis_ints: np.ndarray) -> np.ndarray:
    """Joint positions (f, n, 3) of one sequence coded against a shared basis."""
    magic, n_frames, length, q = _CLIP_HEADER.unpack_from(blob, 0)
    if magic != b"HOUC":
        raise ValueError("not a Hou et al. sequence stream")
    blobs = unpack_blobs(blob[_CLIP_HEADER.size:])
    coefficient_ints = list(decode_ints(blobs[0])) + [decode_ints(b) for b in blobs[1:]]
    return _reconstruct(basis_ints, coefficient_ints, q, [b - a for a, b in segments(n_frames, length)])


def encode_shared(sequences: list[np.ndarray], length: int, k: int, qs: list[int]) -> tuple[bytes, list[bytes]]:
    """One basis stream for all `sequences` and one stream per sequence (with its own Q)."""
    seqs = [_Sequence(p) for p in sequences]
    basis_ints = _shared_basis(seqs, length, k)
    streams = []
    for seq, q in zip(seqs, qs):
        n = min(length, seq.n_frames)
        streams.append(_clip_stream(seq.n_frames, n, q, _quantise(seq.project(n, basis_ints), q)))
    return encode_basis(basis_ints), streams


def _shared_basis(seqs: list[_Sequence], length: int, k: int) -> np.ndarray:
    rows = seqs[0].rows
    k = min(k, rows)
    c = np.zeros((rows, rows))
    for seq in seqs:
        for coef in seq.coefficients(min(length, seq.n_frames)):
            part = coef[:, : dct_count(coef.shape[1], k)]
            c += part @ part.T
    _, vectors = np.linalg.eigh(c)
    b = vectors[:, ::-1][:, :k]
    b = b * np.where(b[np.abs(b).argmax(axis=0), np.arange(k)] < 0, -1.0, 1.0)
    return np.round(b * BASIS_LIMIT).astype(np.int16)


def sweep_shared(sequences: list[np.ndarray], targets, grid_l=GRID_L, grid_k=GRID_K, grid_q=GRID_Q) -> dict:
    """For each target: the shared (L, k) with the fewest total bytes such that every sequence
    meets the target with its own coarsest Q; None when no grid point lets every sequence meet it.

    Returns {target: {"L", "k", "basis_bytes", "sequences": [{"Q", "bytes", errors...}, ...]}}.
    """
    seqs = [_Sequence(p) for p in sequences]
    rows = seqs[0].rows
    best: dict = {t: None for t in targets}
    for length in grid_l:
        for k in sorted({min(k, rows) for k in grid_k}):
            basis_ints = _shared_basis(seqs, length, k)
            basis_bytes = len(encode_basis(basis_ints))
            b = basis_ints.astype(np.float64) / BASIS_LIMIT
            totals = {t: basis_bytes for t in targets}
            chosen: dict = {t: [] for t in targets}
            for seq in seqs:
                n = min(length, seq.n_frames)
                lengths = [y - x for x, y in segments(seq.n_frames, n)]
                coefficients = seq.project(n, basis_ints)
                open_targets = [t for t in targets if totals[t] is not None]
                if not open_targets:
                    break
                if _mean_error(seq.matrix, _synthesise(b, coefficients, lengths)) > max(open_targets):
                    for t in open_targets:
                        totals[t] = None
                    break
                evaluated = {}
                for q in sorted(grid_q):
                    ints = _quantise(coefficients, q)
                    evaluated[q] = (ints, _mean_error(seq.matrix, _synthesise(b, [i * 2.0 ** (-q) for i in ints], lengths)))
                    if evaluated[q][1] <= min(open_targets):
                        break
                encoded: dict = {}
                for t in open_targets:
                    ok = [q for q, (_, e) in evaluated.items() if e <= t]
                    if not ok:
                        totals[t] = None
                        continue
                    q = min(ok)
                    if q not in encoded:
                        ints = evaluated[q][0]
                        stream = _clip_stream(seq.n_frames, n, q, ints)
                        encoded[q] = {"Q": q, "bytes": len(stream),
                                      **errors(seq.positions, _reconstruct(basis_ints, ints, q, lengths))}
                    totals[t] += encoded[q]["bytes"]
                    chosen[t].append(encoded[q])
            for t in targets:
                if totals[t] is not None and len(chosen[t]) == len(seqs) and (
                        best[t] is None or totals[t] < best[t]["bytes"]):
                    best[t] = {"L": length, "k": k, "basis_bytes": basis_bytes, "bytes": totals[t],
                               "sequences": chosen[t]}
    return best


def best(points: list[dict], target: float) -> dict | None:
    """The point with the fewest bytes whose mean error is within `target` (None if none is)."""
    ok = [p for p in points if p["mean_error_cm"] <= target]
    return min(ok, key=lambda p: (p["bytes"], p["mean_error_cm"])) if ok else None
