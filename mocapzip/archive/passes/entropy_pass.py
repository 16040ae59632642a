"""The entropy pass (lossy): the clip streams as stored, from those the class coding holds,
coded again from the archive's priors where they pay (`codec.entropy.priors`)."""

from __future__ import annotations

from dataclasses import dataclass

from mocapzip.archive.passes.class_coding import CodedClasses
from mocapzip.archive.settings import Settings
from mocapzip.codec.entropy.priors import stored_streams


@dataclass(frozen=True)
class StoredClips:
    """The clip streams as the archive stores them."""

    coder: str  # the coefficient coder they use: the settings', "auto" resolved
    streams: dict[str, bytes]  # clip/NNNNN, clip/NNNNN/SSS, and "priors" with the coder "primed"


def entropy_pass(coded: CodedClasses, settings: Settings, jobs: int = 1) -> StoredClips:
    """The clip streams as stored (lossy; nothing for a lossless archive, whose clips the first pass coded)."""
    if settings.lossless:
        return StoredClips(settings.coefficient_coder, {})
    return StoredClips(*stored_streams(coded.interim, settings.coefficient_coder, jobs))
