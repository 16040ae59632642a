"""Old formats' streams, decode only (which format has which: `legacy.format_of`): format 1's
coefficient coder (`ZstdCoder`) and clip stream (`clip_v1`), formats 1 and 2's class streams
(`class_v1`, `class_v2`), and formats 1 to 9's `skeletons` (`skeleton_texts`). Nothing here
encodes: no path can write an old layout.
"""

from __future__ import annotations

import math

import numpy as np

from mocapzip.codec.basis import ClassBasis, read_header, unpack
from mocapzip.codec.clip_stream import CodedClip
from mocapzip.codec.entropy.coefficients import check_matrix_shape, decode_matrices, matrix_shapes
from mocapzip.codec.entropy.zstd import decode_ints, unpack_blobs
from mocapzip.formats.mcz_checks import parse_json
from mocapzip.limits import MAX_VALUES_PER_CLIP
from mocapzip.stages import Stage, register


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


# by `legacy.Format.class_stream` and `clip_stream`; the newest layouts are the codec's
CLASS_DECODERS = {1: class_v1, 2: class_v2}  # 3: `ClassBasis.decode`
CLIP_DECODERS = {1: clip_v1}  # 2: `CodedClip.from_payload`


def skeleton_texts(unpacked: bytes, layout: int, count: int) -> list[str]:
    """The `count` ASF texts (Latin-1: one character per byte) of a `skeletons` stream of
    `legacy.Format.skeletons` layout 1 (formats 1 to 6: a JSON list of str) or 7 (formats 7 to 9:
    the files' bytes packed, `codec.entropy.zstd.unpack_blobs`), its zstd frame already unpacked."""
    if layout == 7:
        texts = [blob.decode("latin-1") for blob in unpack_blobs(unpacked)]
    else:
        texts = parse_json(unpacked)
    if not (isinstance(texts, list) and len(texts) == count
            and all(isinstance(t, str) and max(t, default="\0") <= "\xff" for t in texts)):
        raise ValueError(f"expected {count} ASF texts, as meta lists")
    return texts
