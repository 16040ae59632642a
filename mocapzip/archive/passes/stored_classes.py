"""`mcz append`'s clips coded in the archive's stored classes: each new clip against the stored
basis (the decoder's, quantised) nearest it (`nearest_class`), by the rate control that codes
a class's clips (`ratecontrol.encode.coded_within`), so that its row naming that class is all a
reader needs. `archive.edit.append` keeps a clip there where that measures fewer bytes than the
new class compress's passes code it in (docs/editing.md).
"""

from __future__ import annotations

import numpy as np

from mocapzip.archive.passes.classes import Unit
from mocapzip.codec.basis import ClassBasis
from mocapzip.inputs.clip import ClipReader
from mocapzip.parallel import parallel_map, worker_state
from mocapzip.ratecontrol.encode import MAX_TRUNCATION_SHARE, SEARCH_STRIDE, ClassCoding, coded_within
from mocapzip.ratecontrol.target import CodingTarget
from mocapzip.stages import get_stage

NEAREST_SCORED = 3  # stored bases scored end to end per clip, of those its poses are nearest
_SHARED = worker_state(__name__)  # what the forked workers read: the units, bases, reader and target


def code_in_stored(units: list[Unit], bases: list[ClassBasis], reader: ClipReader, target: CodingTarget,
                   jobs: int = 1) -> list[tuple[int, ClassCoding] | None]:
    """Per unit (a whole clip: one per clip, in clip order), (class, coding) in the stored class
    `nearest_class` picks, or None where it picks none or that class's coding misses the target."""
    _SHARED.update(units=units, bases=bases, reader=reader, target=target,
                   transform=get_stage("transform", target.transform))
    try:
        return parallel_map(_coded_in_nearest, range(len(units)), jobs)
    finally:
        _SHARED.clear()


def _coded_in_nearest(index: int) -> tuple[int, ClassCoding] | None:
    clip, target = _SHARED["units"][index].load(_SHARED["reader"]), _SHARED["target"]
    k = nearest_class(clip, _SHARED["bases"], target.error_cm)
    if k is None:
        return None
    coding = coded_within(clip, _SHARED["bases"][k], _SHARED["transform"], target)
    return (k, coding) if coding.achieved.mean <= target.error_cm else None


def nearest_class(clip, bases: list[ClassBasis], error_cm: float) -> int | None:
    """Of the NEAREST_SCORED bases of the clip's pose width that leave least of its weighted poses
    unexplained (squared residual of the projection, every SEARCH_STRIDE-th frame), the one whose
    projection alone decodes it with the least error, scored end to end on those frames; None if
    none is within MAX_TRUNCATION_SHARE of `error_cm` (as a band is admitted, `encode._admissible`:
    the quantiser needs the rest) or none has the clip's width. The squared residual ranks cheaply
    but weighs joints unlike the error (CMU: 135's basis before 35's for a walk of 07)."""
    frames = slice(None, None, SEARCH_STRIDE)
    poses = clip.poses[frames]
    root = None if clip.root is None else clip.root[frames]
    projected = {k: basis.reconstruct(basis.project(poses)) for k, basis in enumerate(bases)
                 if basis.mean.size == poses.shape[1]}
    nearest = sorted(projected, key=lambda k: float(np.sum((poses - projected[k]) ** 2)))[:NEAREST_SCORED]
    errors = {k: clip.error(projected[k], root, frames)[0] for k in nearest}
    k = min(errors, key=errors.get, default=None)
    return k if k is not None and errors[k] <= MAX_TRUNCATION_SHARE * error_cm else None
