"""The check, before any clip is read: the settings checked (`archive.settings.checked`), the
clips found, and an output refused that exists (without `force`) or is one of the inputs."""

from __future__ import annotations

import os
from dataclasses import dataclass

from mocapzip.archive.settings import Settings, checked
from mocapzip.defaults import UNITS_CM
from mocapzip.formats.errors import MocapFormatError
from mocapzip.inputs.clip import ClipReader
from mocapzip.inputs.discover import ClipSource, find_clips, no_clips


@dataclass(frozen=True)
class Job:
    """What `compress` was asked for, checked."""

    inputs: list  # the paths given
    output: str
    settings: Settings  # checked (the transform's config as its stage writes it); whole, as meta stores it
    sources: tuple[ClipSource, ...]  # the clips found, by stored path
    skip_bad: bool  # a clip that cannot be read is left out and listed instead of stopping the run
    skipped: tuple[dict, ...]  # what finding the clips left out: {"path", "error"} each (`discover.record_skip`)
    units: str | None  # of BVH files' lengths where they cannot be inferred (a `UNITS_CM` name)

    def clip_reader(self, cache_bytes: int | None) -> ClipReader:
        """The reader every pass loads clips through: it keeps them between passes while they fit
        in `cache_bytes` (None: no limit), every clip if the job needs them all."""
        keeps_every_clip = self.settings.class_plan().keeps_every_clip
        return self.settings.clip_reading().reader(None if keeps_every_clip else cache_bytes, self.units)


def check(inputs, output, settings: Settings, asf=None, force: bool = False, skip_bad: bool = False,
          units: str | None = None) -> Job:
    """The job, or the error that stops it before any clip is read: SettingsError, ValueError for
    unknown `units`, FileExistsError for an `output` that exists (unless `force`), MocapFormatError
    for inputs without clips or an `output` that is one of them."""
    settings = checked(settings)
    if units is not None and units not in UNITS_CM:
        raise ValueError(f"units must be one of {', '.join(UNITS_CM)}, got {units!r}")
    if not force and os.path.lexists(output):
        raise FileExistsError(None, "already exists", os.fspath(output))
    skipped = [] if skip_bad else None
    sources = find_clips(inputs, asf=asf, skipped=skipped)
    if not sources and not skipped:
        raise no_clips(inputs)
    _refuse_input_as_output(output, [p for s in sources for p in (s.motion, s.skeleton)]
                            + [p for p in (asf, settings.classes) if p is not None and os.path.isfile(p)])
    return Job(inputs, os.fspath(output), settings, tuple(sources), skip_bad, tuple(skipped or ()), units)


def _refuse_input_as_output(output, inputs: list) -> None:
    """`-o` naming one of the inputs (or a link to it) would replace it with the archive, even with -f."""
    if not os.path.exists(output):
        return
    target = os.stat(output)
    for path in inputs:
        try:
            same = path is not None and os.path.samestat(target, os.stat(path))
        except OSError:  # a dangling link: nothing there to destroy (the clip is refused or skipped on its own)
            continue
        if same:
            raise MocapFormatError(f"is also an input ({path}); refusing to replace it, even with -f", output)
