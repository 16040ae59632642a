"""The entropy pass (lossy): the clip streams as stored, from those the class coding holds,
coded again from the archive's priors where they pay (`codec.entropy.priors`)."""

from __future__ import annotations

from dataclasses import dataclass

from mocapzip.archive.passes.class_coding import CodedClasses
from mocapzip.codec.entropy.priors import stored_streams


@dataclass(frozen=True)
class StoredClips:
    """The clip streams as the archive stores them."""

    coder: str | None  # the coefficient coder they use: the chain's, "auto" resolved; None: lossless, none
    streams: dict[str, bytes]  # clip/NNNNN, clip/NNNNN/SSS, and "priors" with the coder "primed"


def entropy_pass(coded: CodedClasses, chain: dict[str, dict], jobs: int = 1) -> StoredClips:
    """The clip streams as stored, coded with `chain`'s coefficient coder (`Settings.chain`). A lossless
    chain has none: the first pass coded its clips, and nothing is stored here."""
    if "coefficient coder" not in chain:
        return StoredClips(None, {})
    return StoredClips(*stored_streams(coded.interim, chain["coefficient coder"]["id"], jobs))
