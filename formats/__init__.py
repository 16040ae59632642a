"""File formats: Acclaim ASF (skeletons, `asf`), AMC (motions, `amc`), BVH (`bvh`) and the .mcz
container (`mcz`) with the checks its old and new layouts share (`mcz_checks`); the text
handling and number grammar they share (`text`), numbers read and written in compiled code
(`numbers_compiled`, numba), each format's per-value loops beside it (`amc_compiled`,
`bvh_compiled`), and the error types every reader raises (`errors`)."""

from mocapzip.formats.errors import MocapFormatError

__all__ = ["MocapFormatError"]
