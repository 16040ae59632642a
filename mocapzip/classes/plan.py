"""`ClassPlan`: what an archive's settings say of its classes, the part of them
(`archive.settings.Settings.class_plan`) that the first pass, the classes pass and the class
coding take."""

from __future__ import annotations

from dataclasses import dataclass

from mocapzip.classes.auto import parse_auto


@dataclass(frozen=True)
class ClassPlan:
    """How clips are put in classes, and the model each class is coded as."""

    classes: str  # --classes: "pooled", "auto", "auto:K", a table, or a part of the path (`by_name.class_namer`)
    lossless: bool  # clips share no basis: grouped by name alone ("all" for -c auto), never pooled or cut
    segment: bool  # long takes cut at PPCA change points, each segment a unit of its own (`segment`)
    modes: str | None  # --model tensor's pattern of natural modes (`modes`); None: PCA alone

    @property
    def keeps_every_clip(self) -> bool:
        """Whether every clip stays in memory: `-c auto` and `--segment` analyse all their poses together."""
        return not self.lossless and (self.segment or parse_auto(self.classes) is not False)
