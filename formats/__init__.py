"""File formats: Acclaim ASF (skeletons), AMC (motions) and the .mcz archive."""

from mocapzip.formats.errors import MocapFormatError

__all__ = ["MocapFormatError"]
