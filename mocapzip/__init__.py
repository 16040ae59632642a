"""mocapzip: compress motion-capture databases (Acclaim ASF/AMC) into one small .mcz archive."""

__version__ = "0.1.0"
