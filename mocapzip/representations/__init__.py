"""The five pose representations the codec can compress, by name (thesis 3.2.1).

    get_representation("aligned").forward(model, motion) -> Encoded
    get_representation("aligned").inverse(model, encoded, layout) -> channels (F, C)

| name | poses per frame (CMU) | root track |
|---|---|---|
| channels | the 62 AMC values | none |
| positions | 31 joint positions + 30 bone axes = 183 | none |
| aligned | positions without root translation and heading: 180 | x, y, z, yaw |
| scaled | aligned x (universal height / skeleton height) | x, y, z, yaw |
| normalised | aligned with universal bone lengths | x, y, z, yaw |

`get_representation(name, axes_from_positions=True)` leaves out the axes of bones
whose rotation follows from the joint positions (`positions.solved_bones`; CMU:
183 -> 132 and 180 -> 129 values), as the codec does since format 4.
"""

from __future__ import annotations

from .aligned import Aligned
from .base import Encoded, Representation
from .channels import Channels
from .normalised import Normalised
from .positions import Positions
from .scaled import Scaled

_REGISTRY = {flag: {r.name: r for r in (Channels(flag), Positions(flag), Aligned(flag), Scaled(flag), Normalised(flag))}
             for flag in (False, True)}
NAMES = tuple(_REGISTRY[False])


def get_representation(name: str, axes_from_positions: bool = False) -> Representation:
    """The representation called `name` (one of NAMES); see the module doc for the flag."""
    try:
        return _REGISTRY[bool(axes_from_positions)][name]
    except KeyError:
        raise KeyError(f"unknown representation {name!r}; choose one of {', '.join(NAMES)}") from None


__all__ = ["NAMES", "Encoded", "Representation", "get_representation"]
