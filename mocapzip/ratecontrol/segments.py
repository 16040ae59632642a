"""Rate control of a take cut into segments (--segment): the take as a reader decodes it, its
segments joined (`codec.segments.join_decoded`), held to the target as a whole.

Every segment met the target on its coded frames, and the crossfade only mixes frames both
decode well, so the joined take nearly always meets it at once; if not, its segments are coded
again against a target TIGHTER each time, at most TIGHTENINGS times.
"""

from __future__ import annotations

from dataclasses import dataclass

from mocapzip.codec.basis import ClassBasis
from mocapzip.codec.clip_stream import CodedClip, reconstruct
from mocapzip.codec.entropy.priors import INTERIM_CODER
from mocapzip.codec.patches import FramePatches
from mocapzip.codec.segments import OVERLAP, join_decoded
from mocapzip.inputs.clip import LoadedClip
from mocapzip.ratecontrol.encode import code_clip
from mocapzip.ratecontrol.max_error import Achieved, TargetError, achieved
from mocapzip.ratecontrol.target import CodingTarget
from mocapzip.representations.base import ROOT_TRACK_WIDTH

TIGHTENINGS = 8  # times a take's segments are coded again, tighter, if the joined take misses the target
TIGHTER = 0.9  # the target of each new coding, as a share of the one before


@dataclass(frozen=True)
class SegmentCoding:
    """One segment of a take as its class coded it."""

    first: int  # its first frame in the take
    frames: int  # its frames, up to the next cut
    coded_frames: int  # its frames coded: it and OVERLAP frames past its cuts
    basis: ClassBasis  # its class's
    stream: bytes  # `CodedClip.payload`, coded INTERIM_CODER
    error: tuple[float, float]  # mean and max joint error on its coded frames, cm


@dataclass(frozen=True)
class JoinedTake:
    """A segmented take as it is stored: its segments' streams and errors, and what the take
    achieves joined, as a reader decodes it."""

    streams: tuple[bytes, ...]  # per segment, coded INTERIM_CODER
    errors: tuple[tuple[float, float], ...]  # per segment: mean and max on its coded frames, cm
    achieved: Achieved  # the joined take, every joint of every frame as written
    patches: FramePatches | None  # `max_error.achieved`: None without a bound, or with no frame beyond it
    twists: dict  # twist flips for the take's row (`LoadedClip.final_check`)


def joined_take(take: LoadedClip, segments: list[SegmentCoding], segment_clips: list[LoadedClip], transform,
                target: CodingTarget) -> JoinedTake:
    """The take's segments (`segment_clips`: each one's coded frames as a clip) joined within
    target.error_cm, coded again against a tighter aim while the joined take misses it; TargetError
    if it still misses it after TIGHTENINGS tighter codings. Each joined coding is held to
    target.error_cm itself, not to the aim that coded it."""
    aim = target.error_cm
    cores = [(segment.first, segment.frames) for segment in segments]
    streams, errors = [segment.stream for segment in segments], [segment.error for segment in segments]
    for tightening in range(TIGHTENINGS + 1):
        decoded = [reconstruct(CodedClip.from_payload(stream, INTERIM_CODER,
                                                      [(segment.coded_frames, segment.basis.q),
                                                       (segment.coded_frames, ROOT_TRACK_WIDTH)]),
                               segment.basis, transform, target.dead_zone, segment.coded_frames)
                   for stream, segment in zip(streams, segments)]
        check = take.final_check(*join_decoded(decoded, cores, take.motion.n_frames, OVERLAP))
        if check.error[0] <= target.error_cm:  # the user's target: the tighter aims only steer the coding
            break
        if tightening == TIGHTENINGS:
            raise TargetError(f"segments joined to {check.error[0]:.4f} cm, above {target.error_cm:g} cm after "
                              f"{TIGHTENINGS} tighter codings; use a larger -e", take.source.motion)
        aim *= TIGHTER
        codings = [code_clip(clip, segment.basis, transform, aim, target.dead_zone, target.split)
                   for clip, segment in zip(segment_clips, segments)]
        streams = [coding.coded.payload(INTERIM_CODER) for coding in codings]
        errors = [coding.error for coding in codings]
    return JoinedTake(tuple(streams), tuple(errors), *achieved(take, check, target.bounds), check.twists)
