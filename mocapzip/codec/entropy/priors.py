"""The archive's priors (format 3 on): where every clip stream's coefficient models start.

Each clip's stream is coded on its own, so that one clip decodes without the others, and models
that start at 1/2 spend part of every clip learning what the clip before already knew. The
priors (`coefficients.Priors`) are trained on every clip of the archive, and each clip is then
coded again starting from them ("primed"). Rate control sizes and holds the clips' streams coded
INTERIM_CODER until every class is coded; `stored_streams` turns them into the streams stored.
"""

from __future__ import annotations

from mocapzip.codec.clip_stream import CodedClip
from mocapzip.codec.entropy.coefficients import Priors
from mocapzip.codec.entropy.zstd import encode_bytes
from mocapzip.parallel import parallel_map, worker_state
from mocapzip.progress import progress

# clip streams are held coded "context" until all are coded: "primed" needs priors trained on every clip
INTERIM_CODER = "context"


def stored_streams(interim: dict[str, bytes], coder: str, jobs: int = 1) -> tuple[str, dict[str, bytes]]:
    """(the coder used, the clip streams as stored), from the streams coded INTERIM_CODER, by
    name. For "primed" the archive's priors are trained on every clip (in stream order), the clips
    coded again from them, and the priors stored as the "priors" stream. "auto" takes "primed" when
    that is smaller, counting the priors (about 400 bytes: they pay from roughly 10,000 frames on),
    else "context".

    Training carries its models from clip to clip, so it runs here, in order (decoding its
    streams in workers measured slower: the matrices are larger than the streams and quick to
    decode); `jobs` worker processes code the clips again."""
    if coder == "context":
        return coder, interim
    names = sorted(interim)
    priors = Priors.train(_interim_matrices(interim[name]) for name in progress(names, desc="priors", unit="clip"))
    primed = primed_streams(interim, priors, jobs)
    primed["priors"] = encode_bytes(priors.encode())
    if coder == "primed" or sum(map(len, primed.values())) < sum(map(len, interim.values())):
        return "primed", primed
    return "context", interim


def primed_streams(interim: dict[str, bytes], priors: Priors, jobs: int = 1) -> dict[str, bytes]:
    """The clip streams coded INTERIM_CODER, by name, coded again from `priors` ("primed") by `jobs`
    worker processes: the same coefficients, so they decode to the same poses (`mcz append` codes
    new clips from the archive's priors this way)."""
    names = sorted(interim)
    _SHARED["priors"] = priors  # the workers fork from here; each gets its clip's stream as its item
    try:
        return dict(zip(names, parallel_map(_primed_stream, [interim[name] for name in names], jobs)))
    finally:
        _SHARED.clear()


_SHARED = worker_state(__name__)  # the priors the forked workers code the clips from (`_primed_stream`)


def _interim_matrices(stream: bytes) -> list:
    """A clip's coefficient matrices, decoded from its stream as rate control coded it (one
    clip at a time: the coefficients of all clips may be large)."""
    return CodedClip.from_payload(stream, INTERIM_CODER).matrices


def _primed_stream(stream: bytes) -> bytes:
    """A clip's stream (as rate control coded it) coded again, its models starting from the
    archive's priors ("primed")."""
    return CodedClip.from_payload(stream, INTERIM_CODER).payload("primed", _SHARED["priors"])
