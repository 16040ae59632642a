"""Names the options offer, kept here as plain strings so that `mcz --help` starts without
importing NumPy (0.13 s instead of 0.75 s). tests/test_cli_frictions.py holds them to the
registry (`mocapzip.stages.stage_ids("transform")` and `stage_ids("representation")`)."""

TRANSFORMS = ("dct", "dwt", "identity")
REPRESENTATIONS = ("channels", "positions", "aligned", "scaled", "normalised")

# --max-error's default, as a multiple of -e: it removes gross errors for a few per cent more bytes
# (docs/fidelity.md, from `python benchmarks/max_error.py`)
MAX_TO_MEAN = 10.0
