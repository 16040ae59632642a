"""A class's natural modes (actor, style, take ...) from its clips' paths: `--modes REGEX`.

`--model tensor` (`ratecontrol.tensor`) stacks a class's clips into a tensor with one axis per
natural mode, so each clip needs its place on each: the pattern's named groups are the modes,
and what a group matches in a clip's path is the clip's level on that mode. HDM05's
`HDM_(?P<actor>[a-z]+)_` gives an actor mode; Bandai's `_(?P<style>[a-z-]+)_(?P<take>\\d+)\\.bvh$`
a style and a take mode.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass

from mocapzip.limits import MAX_NATURAL_MODES

MAX_PATTERN_CHARS = 1000


def compiled_modes(pattern: str) -> re.Pattern:
    """The pattern, checked to name between 1 and MAX_NATURAL_MODES groups (ValueError otherwise)."""
    if len(pattern) > MAX_PATTERN_CHARS:
        raise ValueError(f"--modes is {len(pattern):,} characters long, more than {MAX_PATTERN_CHARS:,}")
    try:
        compiled = re.compile(pattern)
    except re.error as exc:
        raise ValueError(f"--modes {pattern!r} is not a regular expression: {exc}") from None
    if not 1 <= len(compiled.groupindex) <= MAX_NATURAL_MODES:
        raise ValueError(f"--modes {pattern!r} names {len(compiled.groupindex)} groups: give each natural mode "
                         f"one, (?P<actor>...), 1 to {MAX_NATURAL_MODES} of them")
    return compiled


@dataclass(frozen=True)
class NaturalModes:
    """A class's grid: the modes, each mode's levels (sorted), and each clip's index on each."""

    modes: tuple[str, ...]
    levels: tuple[tuple[str, ...], ...]
    at: tuple[tuple[int, ...], ...]


def natural_modes(paths: list[str], pattern: str) -> NaturalModes | None:
    """The grid the clips at `paths` fill (in their order), or None where they fill none a tensor
    could hold: a path the pattern does not match, two clips at one place, a place of the grid
    with no clip, or no mode of two levels or more. A mode of one level (every clip of the class
    is the first take) is no mode of this class: it is left out."""
    compiled = compiled_modes(pattern)
    found = [compiled.search(path) for path in paths]
    if not paths or not all(found):
        return None
    named = [match.groupdict(default="") for match in found]
    modes = tuple(mode for mode in compiled.groupindex if len({clip[mode] for clip in named}) > 1)
    if not modes:
        return None
    places = [tuple(clip[mode] for mode in modes) for clip in named]
    levels = tuple(tuple(sorted({place[k] for place in places})) for k in range(len(modes)))
    if len(set(places)) != len(places):
        return None
    if len(places) != math.prod(map(len, levels)):  # the places are distinct: as many as the grid's, every one
        return None
    return NaturalModes(modes, levels, tuple(tuple(levels[k].index(v) for k, v in enumerate(place))
                                             for place in places))
