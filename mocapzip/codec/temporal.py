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

__all__ = ["DctTransform", "DwtTransform", "IdentityTransform", "PolyTransform"]


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
