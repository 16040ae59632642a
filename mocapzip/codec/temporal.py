"""Transforms along time, applied to every column of a (frames x curves) array.

Motion curves are smooth, so in a frequency or wavelet basis most of their
energy sits in a few coefficients and the rest quantise to zero.  Every
transform here returns exactly as many coefficients as there are frames, so
a coefficient index always fits a fixed-size integer and a coefficient
matrix has the same shape as the curves.

Which transforms are orthonormal (``orthonormal`` attribute): DCT, identity,
piecewise polynomials, and DWT with an orthogonal wavelet (haar, dbN, symN, coifN).  For those,
the squared error of the coefficients equals the squared error of the
reconstructed curves, so a quantisation error budget can be set directly in
coefficient space.  Biorthogonal wavelets (biorX.Y, rbioX.Y) reconstruct
perfectly but do not preserve energy.
"""

import functools

import numpy as np
import pywt
import scipy.fft

from mocapzip.stages import Stage, register

__all__ = ["DctTransform", "DwtTransform", "EdgeDctTransform", "IdentityTransform", "PolyTransform"]


@register
class DctTransform(Stage):
    """Orthonormal DCT-II per column (scipy.fft, norm="ortho")."""

    kind = "transform"
    codec_id = "dct"
    orthonormal = True

    def forward(self, curves) -> np.ndarray:
        return scipy.fft.dct(np.asarray(curves), type=2, norm="ortho", axis=0)

    def inverse(self, coefs, n_frames: int) -> np.ndarray:
        coefs = _check_length(coefs, n_frames)
        return scipy.fft.idct(coefs, type=2, norm="ortho", axis=0)

    def synthesis(self, n_frames: int, rows: int, frames=slice(None)) -> np.ndarray:
        """(frames, rows): the inverse of each of the first `rows` unit coefficients at `frames`, from
        the DCT-III formula. A few rows decode at a few frames cheaper this way than by `inverse`."""
        t = np.arange(n_frames)[frames, None]
        k = np.arange(rows)[None, :]
        weights = np.where(k == 0, np.sqrt(1.0 / n_frames), np.sqrt(2.0 / n_frames))
        return weights * np.cos(np.pi * k * (2 * t + 1) / (2 * n_frames))



MAX_EDGE_COLUMNS = 64  # more would be no different from a DST-ends transform of every column


@register
class EdgeDctTransform(Stage):
    """The DCT, but the first `edge_columns` columns of each matrix (a clip's pose curves, its root
    track) are coded by their ends: the line through their first and last values, as two
    coefficients (its constant and slope in Gram polynomial coordinates, `gram_polynomials`), and
    the DST-I of what the line leaves between them (zero at both ends, so its odd extension is
    smooth). Exactly T coefficients, perfect reconstruction; clips under 3 frames are all DCT.

    Why: the DCT's basis functions all peak at the clip's ends, so whatever a coding leaves out
    (a band's truncated rows, the coefficients quantised to 0) piles up at the first and last
    frames, where game engines join clips. `python benchmarks/clip_edges.py` at -e 1: the first and
    last 2 frames' mean error was 1.51x the clip's (median) on the 174 Bandai clips and 2.07x on
    CMU's 118; with the ends kept in the first 8 columns (the largest PCA components and the root
    track, whose low frequencies carry most of the error) 1.05x and 1.14x, in 0.6 % and 0.5 %
    fewer bytes. 6 columns were 0.4 % smaller on CMU with 1.21x there; every column, 5 % larger
    (a small component's ends are not where its error is: a DST costs more than a DCT there).
    """

    kind = "transform"
    codec_id = "dct-edges"
    orthonormal = False  # each basis function is unit length, but the line and the sines are not orthogonal
    param_schema = {"edge_columns": {"type": "integer", "minimum": 0, "maximum": MAX_EDGE_COLUMNS}}

    def __init__(self, edge_columns: int = 8):
        if isinstance(edge_columns, bool) or not isinstance(edge_columns, int) \
                or not 0 <= edge_columns <= MAX_EDGE_COLUMNS:
            raise ValueError(f"edge_columns must be an integer from 0 to {MAX_EDGE_COLUMNS}, got {edge_columns!r}")
        self.edge_columns = edge_columns

    def params(self) -> dict:
        return {"edge_columns": self.edge_columns}

    def edge_width(self, n_frames: int, width: int) -> int:
        """How many of a (n_frames, width) matrix's first columns are coded by their ends."""
        return min(self.edge_columns, width) if n_frames >= 3 else 0

    def forward(self, curves) -> np.ndarray:
        curves = np.asarray(curves)
        coefs = scipy.fft.dct(curves, type=2, norm="ortho", axis=0)
        k = self.edge_width(curves.shape[0], 1 if curves.ndim == 1 else curves.shape[1])
        if k:
            ends = np.asarray(curves[:, :k] if curves.ndim == 2 else curves[:, None], dtype=np.float64)
            n = len(ends)
            a, b = (ends[0] + ends[-1]) / 2, (ends[-1] - ends[0]) / (n - 1)  # the line a + b (t - (n - 1) / 2)
            line = a + _centred_times(n)[:, None] * b
            edge = np.empty_like(ends)
            edge[0], edge[1] = a * np.sqrt(n), b * _slope_norm(n)
            edge[2:] = scipy.fft.dst((ends - line)[1:-1], type=1, norm="ortho", axis=0)
            if curves.ndim == 1:
                coefs[:] = edge[:, 0]
            else:
                coefs[:, :k] = edge
        return coefs

    def inverse(self, coefs, n_frames: int) -> np.ndarray:
        coefs = _check_length(coefs, n_frames)
        curves = scipy.fft.idct(coefs, type=2, norm="ortho", axis=0)
        k = self.edge_width(n_frames, 1 if coefs.ndim == 1 else coefs.shape[1])
        if k:
            edge = np.asarray(coefs[:, :k] if coefs.ndim == 2 else coefs[:, None], dtype=np.float64)
            ends = edge[0] / np.sqrt(n_frames) + _centred_times(n_frames)[:, None] * (edge[1] / _slope_norm(n_frames))
            ends[1:-1] += scipy.fft.idst(edge[2:], type=1, norm="ortho", axis=0)
            if coefs.ndim == 1:
                curves[:] = ends[:, 0]
            else:
                curves[:, :k] = ends
        return curves

    def synthesis(self, n_frames: int, rows: int, frames=slice(None), edge: bool = False) -> np.ndarray:
        """(frames, rows): as `DctTransform.synthesis`, or with `edge` for the columns coded by their ends
        (row 0 the constant, row 1 the slope, row r >= 2 the sine of r - 1 half periods)."""
        if not edge:
            return DctTransform().synthesis(n_frames, rows, frames)
        t = np.arange(n_frames)[frames, None].astype(np.float64)
        k = np.arange(rows)[None, :]
        sines = np.sqrt(2.0 / (n_frames - 1)) * np.sin(np.pi * (k - 1) * t / (n_frames - 1))
        return np.where(k == 0, 1 / np.sqrt(n_frames), np.where(k == 1, (t - (n_frames - 1) / 2) / _slope_norm(n_frames),
                                                                 sines))


def _centred_times(n: int) -> np.ndarray:
    return np.arange(n) - (n - 1) / 2


def _slope_norm(n: int) -> float:
    """The length of the centred times 0 - (n - 1) / 2, ..., (n - 1) / 2: sqrt(n (n^2 - 1) / 12)."""
    return float(np.sqrt(n * (n * n - 1) / 12.0))


@register
class DwtTransform(Stage):
    """Multilevel discrete wavelet transform per column, exactly T coefficients for any T.

    Why not plain ``pywt.wavedec``: measured with db4, every extension mode
    returns more than T coefficients for most T (T=100: 101 with
    "periodization", 119 with "symmetric"/"zero"/...).  "periodization" is
    exact and orthogonal for even lengths, so each level here transforms the
    even-length part of the current approximation and passes an odd last
    sample through unchanged.  Layout of the coefficient vector, for one
    level on n samples (recursively inside the approximation part):

        [approximation (n // 2) | odd last sample (n % 2) | details (n // 2)]

    `level=None` uses ``pywt.dwt_max_level(T, filter length)``; a larger
    level stops early once the approximation has fewer than 2 samples.
    """

    kind = "transform"
    codec_id = "dwt"
    param_schema = {"wavelet": {"type": "string"},  # JSON Schema of `params()`, for archive meta
                    "level": {"anyOf": [{"type": "integer", "minimum": 0, "maximum": 32}, {"type": "null"}]}}

    def __init__(self, wavelet: str = "db4", level=None):
        self.wavelet = pywt.Wavelet(wavelet)
        if level is not None and level < 0:
            raise ValueError(f"level must be non-negative or None, got {level}")
        self.level = level
        self.orthonormal = self.wavelet.orthogonal

    def forward(self, curves) -> np.ndarray:
        curves = np.asarray(curves)
        return self._forward(curves, self._levels(curves.shape[0]))

    def inverse(self, coefs, n_frames: int) -> np.ndarray:
        coefs = _check_length(coefs, n_frames)
        return self._inverse(coefs, self._levels(n_frames))

    def _levels(self, n_frames: int) -> int:
        if self.level is not None:
            return self.level
        return pywt.dwt_max_level(n_frames, self.wavelet.dec_len)

    def _forward(self, x: np.ndarray, levels: int) -> np.ndarray:
        n = x.shape[0]
        if levels == 0 or n < 2:
            return x.copy()
        even = n - n % 2
        approximation, details = pywt.dwt(x[:even], self.wavelet, mode="periodization", axis=0)
        return np.concatenate(
            [self._forward(approximation, levels - 1), x[even:], details], axis=0
        )

    def _inverse(self, coefs: np.ndarray, levels: int) -> np.ndarray:
        n = coefs.shape[0]
        if levels == 0 or n < 2:
            return coefs.copy()
        half = n // 2
        approximation = self._inverse(coefs[:half], levels - 1)
        odd_sample = coefs[half : n - half]
        details = coefs[n - half :]
        even_part = pywt.idwt(approximation, details, self.wavelet, mode="periodization", axis=0)
        return np.concatenate([even_part, odd_sample], axis=0)

    def params(self) -> dict:
        return {"wavelet": self.wavelet.name, "level": self.level}


@register
class IdentityTransform(Stage):
    """No transform: coefficients are the curves (baseline, and for noise-like channels)."""

    kind = "transform"
    codec_id = "identity"
    orthonormal = True

    def forward(self, curves) -> np.ndarray:
        return np.array(curves, copy=True)

    def inverse(self, coefs, n_frames: int) -> np.ndarray:
        return _check_length(coefs, n_frames).copy()



MAX_KNOT_SPACING = 512  # frames: a segment's polynomials are an (L, L) matrix, L up to 1.5 x this

@register
class PolyTransform(Stage):
    """Piecewise polynomial fits of each curve (the 2003 page's method, seed 003): the frames
    are cut into segments of about `knot_spacing` frames, and each segment's curve is expressed in
    the orthonormal polynomials of its frames (Gram polynomials: degree 0, 1, ... up to one less
    than the segment's length, so exactly T coefficients, perfect reconstruction).

    Coefficients are laid out by degree, then by segment: every segment's constant term first,
    then every segment's slope, and so on. A band that keeps the first rows therefore keeps
    the same low degrees in every segment: it is the low-pass smoothing, and keeping the first
    rows is a least-squares polynomial fit of that degree per segment. The quantiser zeroes the
    higher terms a segment does not need, which is its degree chosen per segment. The knots are
    uniform, found from T and `knot_spacing` alone (`segment_bounds`), so none is stored.
    """

    kind = "transform"
    codec_id = "poly"
    orthonormal = True
    param_schema = {"knot_spacing": {"type": "integer", "minimum": 1, "maximum": MAX_KNOT_SPACING}}

    def __init__(self, knot_spacing: int = 120):
        if isinstance(knot_spacing, bool) or not isinstance(knot_spacing, int) \
                or not 1 <= knot_spacing <= MAX_KNOT_SPACING:
            raise ValueError(f"knot_spacing must be an integer from 1 to {MAX_KNOT_SPACING} frames, "
                             f"got {knot_spacing!r}")
        self.knot_spacing = knot_spacing

    def params(self) -> dict:
        return {"knot_spacing": self.knot_spacing}

    def forward(self, curves) -> np.ndarray:
        curves = np.asarray(curves)
        by_segment = np.empty(curves.shape, np.result_type(curves.dtype, np.float32))  # integers in: floats out
        bounds = segment_bounds(curves.shape[0], self.knot_spacing)
        for lo, hi in zip(bounds[:-1], bounds[1:]):
            by_segment[lo:hi] = (gram_polynomials(hi - lo).T @ curves[lo:hi]).astype(by_segment.dtype, copy=False)
        return by_segment[degree_order(bounds)]

    def inverse(self, coefs, n_frames: int) -> np.ndarray:
        coefs = _check_length(coefs, n_frames)
        bounds = segment_bounds(n_frames, self.knot_spacing)
        by_segment = np.empty_like(coefs)
        by_segment[degree_order(bounds)] = coefs
        curves = np.empty_like(coefs)
        for lo, hi in zip(bounds[:-1], bounds[1:]):
            curves[lo:hi] = (gram_polynomials(hi - lo) @ by_segment[lo:hi]).astype(coefs.dtype, copy=False)
        return curves


def segment_bounds(n_frames: int, spacing: int) -> list[int]:
    """The knots of `PolyTransform`: n = round(T / spacing) segments (at least one), as equal as
    integers allow, segment i being frames [i T // n, (i + 1) T // n); so none is longer than
    1.5 x spacing + 1 frames, which bounds `gram_polynomials`."""
    count = max(1, (n_frames + spacing // 2) // spacing)
    return [i * n_frames // count for i in range(count + 1)]


def degree_order(bounds: list[int]) -> np.ndarray:
    """Row r of the coefficients, by degree then segment, is row `order[r]` of the segments'
    coefficients stacked segment after segment (each segment's own in degree order)."""
    starts = np.repeat(bounds[:-1], np.diff(bounds))
    degree = np.arange(bounds[-1]) - starts
    return np.lexsort((starts, degree))


@functools.lru_cache(maxsize=32)
def gram_polynomials(n: int) -> np.ndarray:
    """(n, n): column k is the degree-k polynomial orthonormal over n equally spaced points
    t_i = (2i - (n - 1)) / (n - 1), with a positive leading coefficient (t = 0 for n = 1).

    Built by the Stieltjes procedure: column k is t times column k - 1, orthogonalised against
    the columns before it twice (classical Gram-Schmidt run twice is orthogonal to rounding),
    then normalised. A fit through a Vandermonde matrix would lose the high degrees to its
    conditioning."""
    t = (2.0 * np.arange(n) - (n - 1)) / max(n - 1, 1)
    q = np.empty((n, n))
    q[:, 0] = 1.0 / np.sqrt(n)
    for k in range(1, n):
        v = t * q[:, k - 1]
        for _ in range(2):
            v = v - q[:, :k] @ (q[:, :k].T @ v)
        q[:, k] = v / np.linalg.norm(v)
    q.flags.writeable = False
    return q


def _check_length(coefs, n_frames: int) -> np.ndarray:
    coefs = np.asarray(coefs)
    if coefs.shape[0] != n_frames:
        raise ValueError(f"expected {n_frames} coefficients along axis 0, got {coefs.shape[0]}")
    return coefs
