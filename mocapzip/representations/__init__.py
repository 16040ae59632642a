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

One module each: `channels.py`, `positions.py`, `aligned.py`, `scaled.py`, `normalised.py`, on
`base.py` (the `Representation` stage, the `Encoded` it returns and the `PoseDecoder` it decodes
with); `scaled` and `normalised` are `aligned.RescaledAligned`s, `universal.py` the universal
body they map clips to, and `weighted.py` the codec's weighted pose space and the one decode tail
back to AMC channels, which runs each representation's own decoder (`positions.MarkerDecoder`,
compiled, for all but `channels`).
"""

from __future__ import annotations

from mocapzip.representations.base import Encoded, Representation
# imported in the thesis's order, which is the registry's (and `mcz --help`'s) order
from mocapzip.representations.channels import Channels
from mocapzip.representations.positions import Positions
from mocapzip.representations.aligned import Aligned
from mocapzip.representations.scaled import Scaled
from mocapzip.representations.normalised import Normalised


def get_representation(name: str, axes_from_positions: bool = False) -> Representation:
    """The representation called `name` (a registered id, `mocapzip.stages`); see the module doc for the flag."""
    from mocapzip.stages import get_stage

    return get_stage("representation", {"id": name, "axes_from_positions": bool(axes_from_positions)})


__all__ = ["Aligned", "Channels", "Encoded", "Normalised", "Positions", "Representation", "Scaled",
           "get_representation"]
