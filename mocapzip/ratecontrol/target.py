"""What lossy coding is held to and codes with: `CodingTarget`, the part of an archive's settings
(`archive.settings.Settings.coding_target`) that rate control and -c auto's byte model
(`classes.auto`) read, and its `Bounds` on single joints."""

from __future__ import annotations

from dataclasses import dataclass

from mocapzip.defaults import ACL_SHELL_CM


@dataclass(frozen=True)
class Bounds:
    """What holds single joints, beside the mean: what `max_error.achieved` enforces."""

    max_error_cm: float | None = None  # every joint of every frame
    contact_error_cm: float | None = None  # planted foot joints (`motion.contacts`)
    repair_glitches: bool = False  # the joints a source glitch throws off are not held (`glitches.glitch_mask`)
    vertex_error_cm: float | None = None  # every shell vertex of every frame (ACL's metric, `motion.metrics`)
    shell_cm: float = ACL_SHELL_CM  # the shell vertices' distance from their bone, cm

    @property
    def on_joints(self) -> bool:
        """Whether any joint or vertex has a bound of its own (then patches may be needed)."""
        return self.max_error_cm is not None or self.contact_error_cm is not None or self.vertex_error_cm is not None


@dataclass(frozen=True)
class CodingTarget:
    """A lossy archive's target and the knobs its coding turns."""

    error_cm: float  # each clip's mean joint error, at most
    bounds: Bounds  # on single joints
    plant_feet: bool  # the decoder holds the source's planted feet still (`planted_feet`)
    transform: dict  # the temporal transform's config (a registered stage)
    dead_zone: float  # the quantiser's
    basis_precision: float  # a basis's rounding error per direction, as a share of error_cm (docs/fixed_costs.md)
    split: tuple[float, ...] | None = None  # forced R, P, T shares of error_cm (the thesis's experiments)
