"""File formats: Acclaim ASF (skeletons, `asf`), AMC (motions, `amc`), BVH (`bvh`) and the .mcz
container (`mcz`); the text handling and number grammar they share (`text`), the per-value loops of
AMC and BVH compiled with numba (`amc_compiled`), and the one error type every reader raises
(`errors`)."""

from mocapzip.formats.errors import MocapFormatError

__all__ = ["MocapFormatError"]
