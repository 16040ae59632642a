"""What decides an archive's content: `Settings`, stored whole in its meta, and the chain of
registered stages (`mocapzip.stages`) they name, checked before any input is read."""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

from mocapzip.classes.modes import compiled_modes
from mocapzip.classes.plan import ClassPlan
from mocapzip.defaults import (ACL_SHELL_CM, AUTO_REPRESENTATION, CHANNELS_BELOW_CM_HZ, CHANNELS_BELOW_VERTEX_CM_HZ,
                               DEFAULT_FPS)
from mocapzip.inputs.clip import ClipReading
from mocapzip.ratecontrol.target import Bounds, CodingTarget
from mocapzip.stages import get_stage, stage_ids

DEFAULT_ERROR_CM = 1.0
# Errors and bounds above this mean nothing for a body (10 km) and overflow the step arithmetic
# (`-e 1e200`: OverflowError in `codec.basis.steps_for`, which squares them).
MAX_ERROR_CM = 1e6
# Below this (10 nm) no capture is exact: what must come back exactly is --lossless's. Far below it the
# quantiser's integers pass the 2**62 a stream holds (`-e 1e-17` on cmu/09, `-e 1e-20` on a small BVH:
# ValueError in `encode_matrices`); 1e-9 coded cmu/09, and BVH clips of roots 9e6 cm out, at 0 cm.
MIN_ERROR_CM = 1e-6
AUTO_CODER = "auto"  # compress only: "primed" when the priors pay for themselves, else "context"


@dataclass
class Settings:
    """Everything that decides the archive's content; stored in it as JSON."""

    error_cm: float = DEFAULT_ERROR_CM
    max_error_cm: float | None = None  # bound on every joint of every frame (frame patches); None: no bound
    contact_error_cm: float | None = None  # bound on planted foot joints (motion.contacts; frame patches); None: none
    # bound on every shell vertex of every frame, ACL's metric (motion.metrics.shell_errors; frame patches;
    # format 13 on); None: none. `shell_cm`: the vertices' distance from their bone (format 13 on; absent: 3)
    vertex_error_cm: float | None = None
    shell_cm: float = ACL_SHELL_CM
    repair_glitches: bool = False  # joints a source glitch throws off are left to the decoder, not held to the bounds
    plant_feet: bool = False  # the decoder holds the source's planted feet still (codec.foot_lock; format 9 on)
    # a registered representation, or "auto" (compress only): `chosen_representation`. Archives store the one used.
    representation: str = AUTO_REPRESENTATION
    # the temporal transform (a registered stage's config): the DCT, with the first 8 columns of each
    # matrix coded by their ends (`codec.temporal.EdgeDctTransform`; format 13 on)
    transform: dict = field(default_factory=lambda: {"id": "dct-edges", "edge_columns": 8})
    classes: str = "pooled"
    split: list[float] | None = None  # forced R, P, T shares of error_cm
    dead_zone: float = 0.2
    basis_precision: float = 0.04  # basis rounding error per direction, as a share of error_cm (docs/fixed_costs.md)
    axis_weight_cm: float = 12.0  # weight of bone axis vectors against positions (Representation.column_weights; solved_bones.py)
    fps: float = DEFAULT_FPS  # clips' frame rate where their files state none (ASF/AMC have no field for it)
    fps_from_files: bool = True  # a rate the clip's files state wins over `fps` (False: --fps given, for all)
    lossless: bool = False
    segment: bool = False  # cut long takes at PPCA change points, each segment coded on its own
    # clip streams' coefficient coder: "primed" (models start from the archive's priors; format 3 on),
    # "context" (models start at 1/2; format 2 on), "zstd" (format 1, read only); "auto" (compress
    # only): "primed" when the priors pay for themselves, else "context". Archives store the coder used.
    coefficient_coder: str = AUTO_CODER
    # bones whose rotation follows from joint positions store no axis (representations.positions.solved_bones);
    # absent, in formats 1 to 3: false
    axes_from_positions: bool = True
    # "tensor" (format 11 on): a class whose clips fill a grid of natural modes (`modes`, a pattern whose
    # named groups each clip's path matches: classes.modes) is also coded as a tensor model's prediction
    # plus what it misses, and keeps whichever is smaller (ratecontrol.tensor). Absent: "pca"
    model: str = "pca"
    modes: str | None = None

    def chain(self) -> dict[str, dict]:
        """The config of every stage these settings name, by kind: all a decoder needs."""
        if self.lossless:
            return {"lossless coder": {"id": "decimal"}}
        return {"representation": {"id": self.representation, "axes_from_positions": self.axes_from_positions},
                "transform": self.transform,
                "quantiser": {"id": "uniform", "dead_zone": self.dead_zone},
                "coefficient coder": {"id": self.coefficient_coder}}

    def stages(self) -> dict:
        """The stages of `chain()`, built from the registry (ValueError for an unknown one)."""
        return {kind: get_stage(kind, config) for kind, config in self.chain().items()}

    def clip_reading(self) -> ClipReading:
        """What reading the clips takes of these settings: the first pass and its reader take this part."""
        return ClipReading(None if self.lossless else self.representation, self.axis_weight_cm,
                           self.axes_from_positions, self.fps, self.fps_from_files, self.repair_glitches)

    def class_plan(self) -> ClassPlan:
        """What the classes take of these settings: the first pass, the classes pass and the class coding
        take this part (`checked` settings name modes with --model tensor alone)."""
        return ClassPlan(self.classes, self.lossless, self.segment and not self.lossless, self.modes)

    def coding_target(self) -> CodingTarget:
        """What lossy coding reads of these settings: rate control and -c auto's byte model take this part."""
        return CodingTarget(self.error_cm, Bounds(self.max_error_cm, self.contact_error_cm, self.repair_glitches,
                                                  self.vertex_error_cm, self.shell_cm),
                            self.plant_feet, self.transform, self.dead_zone, self.basis_precision,
                            None if self.split is None else tuple(self.split))


class SettingsError(ValueError):
    """Settings an archive of this format cannot hold; raised before any input is read."""


def written_coders() -> tuple[str, ...]:
    """Coefficient coders `compress` accepts: those the newest format writes, and "auto"."""
    return (AUTO_CODER, *stage_ids("coefficient coder", written_only=True))


def chosen_representation(settings: Settings) -> str:
    """The representation compress uses: the one named, or for "auto" the smaller by measure at
    the error and vertex bound asked for, relative to `fps` (`defaults.CHANNELS_BELOW_CM_HZ`;
    clips whose files state another rate are judged at `fps` all the same; lossless archives name
    "aligned", as before "auto", for a representation they do not use)."""
    if settings.representation != AUTO_REPRESENTATION:
        return settings.representation
    vertex = math.inf if settings.vertex_error_cm is None else settings.vertex_error_cm
    tight = not settings.lossless and (settings.error_cm * settings.fps < CHANNELS_BELOW_CM_HZ
                                       or vertex * settings.fps < CHANNELS_BELOW_VERTEX_CM_HZ)
    return "channels" if tight else "aligned"


def checked(settings: Settings) -> Settings:
    """`settings` with the transform's config as its stage writes it (pywt takes 'DB4' for
    'db4'; readers check the name), or SettingsError for an unknown stage, a number that is not
    finite, or a coder only old formats wrote (format 1's "zstd": read, never written); a
    representation of "auto" resolved (`chosen_representation`)."""
    from mocapzip.formats.mcz import FORMAT_VERSION

    settings = replace(settings, representation=chosen_representation(settings))
    if settings.coefficient_coder not in written_coders():
        raise SettingsError(f"coefficient_coder {settings.coefficient_coder!r} is not written by format "
                            f"{FORMAT_VERSION}; choose one of {', '.join(written_coders())}")
    if settings.plant_feet and (settings.segment or settings.lossless):
        raise SettingsError("plant_feet does not combine with " + ("lossless: every value comes back as it was"
                            if settings.lossless else "segment: a segmented take's streams hold no stances"))
    if settings.model not in ("pca", "tensor"):
        raise SettingsError(f"model must be pca or tensor, got {settings.model!r}")
    if (settings.model == "tensor") != (settings.modes is not None):
        raise SettingsError("--model tensor needs --modes, and --modes is for --model tensor")
    if settings.model == "tensor":
        if settings.lossless or settings.segment:
            raise SettingsError(f"--model tensor does not combine with {'--lossless' if settings.lossless else '--segment'}")
        try:
            compiled_modes(settings.modes)
        except ValueError as exc:
            raise SettingsError(str(exc)) from None
    bounds = {"max_error_cm": settings.max_error_cm, "contact_error_cm": settings.contact_error_cm,
              "vertex_error_cm": settings.vertex_error_cm}
    bounds = {name: bound for name, bound in bounds.items() if bound is not None}
    for name, bound in {"error_cm": settings.error_cm, **bounds}.items():
        if not MIN_ERROR_CM <= bound <= MAX_ERROR_CM:
            raise SettingsError(f"{name} must be from {MIN_ERROR_CM:g} to {MAX_ERROR_CM:g} cm (exact values: "
                                f"--lossless), got {bound}")
    if not 0 <= settings.shell_cm <= MAX_ERROR_CM:  # 0: the vertices are the bones' origins, joints
        raise SettingsError(f"shell_cm must be from 0 to {MAX_ERROR_CM:g} cm, got {settings.shell_cm}")
    numbers = [settings.error_cm, *bounds.values(), settings.shell_cm, settings.dead_zone, settings.basis_precision, settings.axis_weight_cm,
               settings.fps, *(settings.split or [])]
    if not all(math.isfinite(x) for x in numbers):
        raise SettingsError("settings must be finite numbers (no inf or nan)")
    try:  # both chains, whichever is used: a bad name is refused either way ("auto" is resolved later)
        lossy = replace(settings, lossless=False, coefficient_coder="context").stages()
        replace(settings, lossless=True).stages()
    except (ValueError, KeyError) as exc:
        raise SettingsError(str(exc).strip('"')) from None
    return replace(settings, transform=lossy["transform"].get_config())
