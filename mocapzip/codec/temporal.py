"""Transforms along time, applied to every column of a (frames x curves) array.

Motion curves are smooth, so in a frequency or wavelet basis most of their
energy sits in a few coefficients and the rest quantise to zero.  Every
transform here returns exactly as many coefficients as there are frames, so
a coefficient index always fits a fixed-size integer and a coefficient
matrix has the same shape as the curves.

Which transforms are orthonormal (``orthonormal`` attribute): DCT, identity,
and DWT with an orthogonal wavelet (haar, dbN, symN, coifN).  For those,
the squared error of the coefficients equals the squared error of the
reconstructed curves, so a quantisation error budget can be set directly in
coefficient space.  Biorthogonal wavelets (biorX.Y, rbioX.Y) reconstruct
perfectly but do not preserve energy.
"""

import numpy as np
import pywt
import scipy.fft

from mocapzip.stages import Stage, register

__all__ = ["DctTransform", "DwtTransform", "IdentityTransform"]


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



def _check_length(coefs, n_frames: int) -> np.ndarray:
    coefs = np.asarray(coefs)
    if coefs.shape[0] != n_frames:
        raise ValueError(f"expected {n_frames} coefficients along axis 0, got {coefs.shape[0]}")
    return coefs
