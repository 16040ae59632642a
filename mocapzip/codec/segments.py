"""A take cut into segments (`mcz compress --segment`, cut by `classes.segment`), as coded and
joined again: the `clip/NNNNN/SSS` streams of one take.

Each segment is coded over a range reaching OVERLAP frames past its cuts (`coded_range`),
because a transform-coded curve is least accurate at its ends (about ten frames at 120 Hz);
`join_segments` then crossfades neighbours over the middle half of the overlap, where both are
accurate, so the seam neither jumps nor carries an edge's error.
"""

from __future__ import annotations

import numpy as np

OVERLAP = 16  # frames a segment is coded past each of its cuts (stored per take: the decoder reads it)


def coded_range(first: int, frames: int, n_frames: int, overlap: int = OVERLAP) -> tuple[int, int]:
    """Frames [lo, hi) of a take coded for the segment of `frames` frames from `first`."""
    return max(first - overlap, 0), min(first + frames + overlap, n_frames)


def join_segments(pieces: list[np.ndarray], segments: list[tuple[int, int]], n_frames: int,
                  overlap: int = OVERLAP) -> np.ndarray:
    """One take (n_frames, ...) from its segments' decoded `pieces`, each over its `coded_range`.

    `segments` are the (first, frames) of each segment, partitioning the take in order.
    Around a cut c the weight moves linearly from the earlier piece to the later over
    [c - overlap/2, c + overlap/2) (overlap >= 2); the weights sum to one on every frame.
    """
    half = overlap // 2
    centres = np.arange(n_frames) + 0.5
    out = np.zeros((n_frames,) + pieces[0].shape[1:])
    for s, (piece, (first, frames)) in enumerate(zip(pieces, segments)):
        lo, hi = coded_range(first, frames, n_frames, overlap)
        weight = np.ones(hi - lo)
        if s > 0:
            weight = np.minimum(weight, np.clip((centres[lo:hi] - first + half) / (2 * half), 0, 1))
        if s < len(pieces) - 1:
            weight = np.minimum(weight, np.clip((first + frames + half - centres[lo:hi]) / (2 * half), 0, 1))
        out[lo:hi] += weight.reshape((-1,) + (1,) * (piece.ndim - 1)) * piece
    return out


def join_decoded(decoded: list, cores: list[tuple[int, int]], n_frames: int, overlap: int):
    """(poses, root) of a take from its segments' decoded (poses, root) (`join_segments`)."""
    poses = join_segments([p for p, _ in decoded], cores, n_frames, overlap)
    root = None if decoded[0][1] is None else join_segments([r for _, r in decoded], cores, n_frames, overlap)
    return poses, root
