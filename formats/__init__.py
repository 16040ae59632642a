"""File formats: Acclaim ASF (skeletons), AMC (motions) and the .mcz archive."""

from .errors import MocapFormatError

__all__ = ["MocapFormatError"]
