"""Scalar quantisation: the one lossy step between transforms and entropy coding.

`UniformQuantiser` maps coefficients to integers with a fixed step.  An
optional dead zone widens the bin around zero: small coefficients, which are
mostly noise, then become 0 and the entropy coder stores long zero runs for
almost nothing.

`quantise_to_bits` stores a small float matrix (a PCA basis, for example)
with a fixed number of bits per entry and one float32 scale per column, so
columns of very different magnitudes each get the full precision.
"""

import numpy as np

__all__ = ["UniformQuantiser", "quantise_to_bits", "dequantise_from_bits"]

# |x| / step must stay below this so the integer (and later zigzag codes) fit int64.
_MAX_LEVEL = 2.0**62


class UniformQuantiser:
    """q = sign(x) * max(floor(|x| / step + 0.5 - dead_zone), 0); x is restored as q * step.

    With dead_zone == 0 this is rounding to the nearest multiple of step, so
    |x - dequantise(quantise(x))| <= step / 2.  A dead zone d moves every
    threshold away from zero by d * step (the zero bin becomes
    (0.5 + d) * step wide on each side) and the error bound becomes
    (0.5 + d) * step.  Restoring at q * step rather than at the bin centre
    keeps the decoder independent of d and is the usual choice for
    coefficients that are denser near zero.
    """

    codec_id = "uniform"

    def __init__(self, step: float, dead_zone: float = 0.0):
        if not (np.isfinite(step) and step > 0):
            raise ValueError(f"step must be a positive finite number, got {step}")
        if not 0.0 <= dead_zone < 0.5:
            raise ValueError(f"dead_zone must be in [0, 0.5), got {dead_zone}")
        self.step = float(step)
        self.dead_zone = float(dead_zone)

    def quantise(self, x) -> np.ndarray:
        levels = np.abs(np.asarray(x, np.float64)) / self.step
        if not np.all(levels < _MAX_LEVEL):  # also rejects NaN and infinity
            raise ValueError("values are not finite or too large for this step")
        magnitude = np.maximum(np.floor(levels + 0.5 - self.dead_zone), 0.0)
        return (np.sign(x) * magnitude).astype(np.int64)

    def dequantise(self, q) -> np.ndarray:
        return np.asarray(q, np.int64) * self.step

    def get_config(self) -> dict:
        return {"id": self.codec_id, "step": self.step, "dead_zone": self.dead_zone}

    @classmethod
    def from_config(cls, config: dict) -> "UniformQuantiser":
        """Rebuild from `get_config()` output (the "id" entry is optional)."""
        return cls(**{key: value for key, value in config.items() if key != "id"})

    def __repr__(self) -> str:
        return f"UniformQuantiser(step={self.step!r}, dead_zone={self.dead_zone!r})"


def quantise_to_bits(x, bits: int):
    """Quantise each column of a 2-D matrix to signed `bits`-bit integers.

    Returns (ints, scales): int64 array of x's shape with |ints| <=
    2**(bits - 1) - 1, and float32 scales, one per column, such that
    ``dequantise_from_bits(ints, scales)`` is within scale / 2 of x.  The
    scales are float32 because that is how they are stored; quantising with
    the rounded scale keeps that bound exact.  An all-zero column gets scale 0.
    """
    x = np.asarray(x, np.float64)
    if x.ndim != 2:
        raise ValueError(f"expected a 2-D matrix, got shape {x.shape}")
    if not 2 <= bits <= 32:
        raise ValueError(f"bits must be between 2 and 32, got {bits}")
    if not np.all(np.isfinite(x)):
        raise ValueError("matrix contains NaN or infinity")
    largest = 2 ** (bits - 1) - 1
    peak = np.abs(x).max(axis=0, initial=0.0)
    scales = (peak / largest).astype(np.float32)
    # float32 rounding may have made a scale too small for the peak to fit; bump it.
    too_small = scales.astype(np.float64) * largest < peak
    scales[too_small] = np.nextafter(scales[too_small], np.float32(np.inf))
    safe = np.where(scales > 0, scales, 1.0).astype(np.float64)
    ints = np.clip(np.rint(x / safe), -largest, largest).astype(np.int64)
    return ints, scales


def dequantise_from_bits(ints, scales) -> np.ndarray:
    """Inverse of `quantise_to_bits`: ints * scale per column, as float64."""
    return np.asarray(ints, np.int64) * np.asarray(scales, np.float32).astype(np.float64)
