"""Old archive formats, decode only, in one place (as zstd keeps `lib/legacy`).

The reader (`mocapzip.archive.reader`) dispatches on the container's `format_version`; what
format 4 and every later format do is decoded by the codec modules (what formats 7 and 10
changed in the `meta` and `skeletons` streams by the reader's own branches), and only what
formats 1 to 3 did differently lives here. Nothing here encodes: no path can write an old layout.

| format_version | differs from format 4 in |
|---|---|
| 1 | settings name no `coefficient_coder` (its streams are "zstd": `ZstdCoder`, `class_v1`, `clip_v1`) nor `axes_from_positions` (false) |
| 2 | class streams hold mean and basis integers, no reference rows (`class_v2`); coder "context" only; no `axes_from_positions` (false) |
| 3 | no `axes_from_positions` (false: every bone stores its axis) |

The lossless channel code keeps its own layout number in each stream (1: the first format-1
writers, before the rANS residual coder; 2: every later writer), read by `mocapzip.codec.lossless`.
"""

from __future__ import annotations

import math

import numpy as np

from mocapzip.codec.basis import ClassBasis, read_header, unpack
from mocapzip.codec.clip_stream import CodedClip
from mocapzip.codec.entropy.coefficients import check_matrix_shape, decode_matrices, matrix_shapes
from mocapzip.codec.entropy.zstd import decode_ints
from mocapzip.limits import MAX_VALUES_PER_CLIP
from mocapzip.stages import Stage, register

# settings fields an older format did not store, as that format meant them
SETTINGS_DEFAULTS = {
    1: {"coefficient_coder": "zstd", "axes_from_positions": False},
    2: {"axes_from_positions": False},
    3: {"axes_from_positions": False},
}
# the coefficient coders each format wrote (format 4: as format 3)
CODERS = {1: ("zstd",), 2: ("context",), 3: ("context", "primed")}


@register
class ZstdCoder(Stage):
    """Format 1's coefficient coder: `u8 count`, then per matrix a `u32` length and an ints blob
    (`codec.entropy.zstd.decode_ints`). Read only."""

    kind = "coefficient coder"
    codec_id = "zstd"
    needs_priors = False
    decode_only = True

    def decode(self, blob: bytes, shapes=None, priors=None) -> list[np.ndarray]:
        (count,) = unpack("<B", blob, 0)
        if not 1 <= count <= 2:
            raise ValueError(f"clip payload holds {count} matrices")
        pos, arrays = 1, []
        # each matrix at most the values its expected shape holds (unknown: an AMC clip's)
        most = [math.prod(shape) for shape in shapes] if shapes is not None else [MAX_VALUES_PER_CLIP] * count
        for k in range(count):
            (size,) = unpack("<I", blob, pos)
            arrays.append(decode_ints(blob[pos + 4 : pos + 4 + size], most[k]))
            pos += 4 + size
            if arrays[-1].ndim != 2:
                raise ValueError(f"clip payload holds a matrix of shape {arrays[-1].shape}")
            check_matrix_shape(*arrays[-1].shape)
        if pos != len(blob):
            raise ValueError("clip payload has trailing bytes")
        if shapes is not None and [a.shape for a in arrays] != [tuple(s) for s in shapes][:count]:
            raise ValueError(f"clip matrices of shapes {[a.shape for a in arrays]}, expected {list(shapes)}")
        return arrays


def clip_v1(blob: bytes, shapes=None) -> CodedClip:
    """Format 1's clip stream: `f64 pose_step`, `f64 root_step`, then `ZstdCoder`'s matrices."""
    pose_step, root_step = unpack("<dd", blob, 0)
    arrays = ZstdCoder().decode(blob[16:], shapes)
    return CodedClip(pose_step, arrays[0], root_step, arrays[1] if len(arrays) > 1 else None)


def class_v1(blob: bytes) -> ClassBasis:
    """Format 1's class stream: the header, then the mean's and the basis's integers as two
    `u32`-length-prefixed ints blobs."""
    m, q, steps, pos = read_header(blob)
    parts = []
    for values in (m, m * q):
        (n,) = unpack("<I", blob, pos)
        parts.append(decode_ints(blob[pos + 4 : pos + 4 + n], values))
        pos += 4 + n
    if pos != len(blob):
        raise ValueError("class basis has trailing bytes")
    return ClassBasis.from_integers(m, parts[0], parts[1], steps)


def class_v2(blob: bytes) -> ClassBasis:
    """Format 2's class stream: the header, then one "context" matrices stream of the mean's
    integers (M x 1) and the basis integers themselves (M x Q)."""
    m, q, steps, pos = read_header(blob)
    expected = [(m, 1), (m, q)]
    stored = matrix_shapes(blob[pos:])
    if stored != expected:
        raise ValueError(f"class basis matrices of shapes {stored} for a {m} x {q} basis")
    mean_ints, ints = decode_matrices(blob[pos:], expected)
    return ClassBasis.from_integers(m, mean_ints, ints, steps)


CLASS_DECODERS = {1: class_v1, 2: class_v2}  # other formats: ClassBasis.decode
CLIP_DECODERS = {1: clip_v1}  # other formats: CodedClip.from_payload
