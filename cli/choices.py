"""Names and defaults the options offer, kept here as plain values so that `mcz --help` starts
without importing NumPy (0.13 s instead of 0.75 s). tests/test_cli_frictions.py holds them to the
registry (`mocapzip.stages.stage_ids("transform")` and `stage_ids("representation")`)."""

import math

import click

from mocapzip.defaults import MAX_TO_MEAN, UNITS_CM  # --max-error's default, as a multiple of -e

UNITS = tuple(UNITS_CM)  # --units: BVH length units
TRANSFORMS = ("dct-edges", "dct", "dwt", "poly", "identity")
REPRESENTATIONS = ("channels", "positions", "aligned", "scaled", "normalised")

CONTACT_ERROR_CM = None  # --contact-error's default: off (its cost and foot skate: docs/fidelity.md)


def max_error_value(ctx, param, value):
    """--max-error CM or 'none' (compress, bench); None (not given) stands for the default, MAX_TO_MEAN x -e."""
    if value is None or value.lower() == "none":
        return value and "none"
    try:
        bound = float(value)
    except ValueError:
        bound = math.nan
    if not (math.isfinite(bound) and bound > 0):
        raise click.BadParameter(f"expected a number of cm above 0, or 'none'; got {value!r}", ctx, param)
    return bound


def contact_error_cm(option) -> float | None:
    """The bound --contact-error `option` (as `max_error_value` gave it) sets; None (not given): CONTACT_ERROR_CM."""
    if option is None:
        return CONTACT_ERROR_CM
    return None if option == "none" else option


def max_error_cm(option, error_cm: float) -> float | None:
    """The bound --max-error `option` (as `max_error_value` gave it) sets for mean target `error_cm`."""
    if option is None:
        return MAX_TO_MEAN * error_cm
    return None if option == "none" else option
