"""`--model tensor`: a class coded as a tensor model's prediction plus what it misses (Krüger et
al. 2007, seed 002, section 2).

A class whose clips fill a grid of natural modes (actor x style x take ...: `classes.modes`) is
a tensor once its clips are warped to one timeline: each is aligned to the class's longest clip
by multiscale DTW on physics features (`motion.timewarp`, `motion.physics`) and carried onto it.
The tensor, less the class's mean pose, is reduced by N-mode SVD (`codec.tensor.hooi`) and
stored (`TensorModel`). Each clip's prediction is the model at its levels, carried back onto
its own timeline by its warping path, and the clip is coded as the difference, by the class's
usual PCA + temporal coding of `encode_class`: so every clip meets the error target end to end
exactly as without the model, which can cost bytes but never error.

The model pays only if its bytes and the paths' are less than what it saves the clips. Each
class is coded without it and with it at a few ranks (`RANKS`); the smallest wins, and a
class where plain PCA wins is stored as one (`mcz info` shows which). So does a class whose
tensor would hold more than MAX_TENSOR_VALUES values, or whose clips no warping path aligns; a
choice of ranks whose model would store more than a reader takes (`check_model_sizes`: a long
class at 1/8 of its frames) is not tried. A tensor class is coded in one process, all its clips
in memory at once.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, fields
from functools import cached_property

import numpy as np

from mocapzip.codec.entropy.zstd import encode_bytes
from mocapzip.codec.tensor import TensorModel, check_model_sizes, hooi, prediction
from mocapzip.inputs.clip import LoadedClip
from mocapzip.motion.kinematics import forward
from mocapzip.motion.physics import physics_features
from mocapzip.motion.timewarp import Warping, multiscale_dtw, path_moves
from mocapzip.ratecontrol.encode import encode_class
from mocapzip.ratecontrol.target import CodingTarget

# ranks tried: of the frames and pose-value modes as shares of their sizes, and of each natural
# mode (None: all its levels; 1: the class's one warped motion). On the shared data the best of
# them took 1.13 to 2.47 times PCA's bytes, and no class took the model (docs/seed_methods.md,
# `python benchmarks/tensor.py --codec`).
RANKS = ((1 / 32, 1 / 32, 1), (1 / 16, 1 / 16, 1), (1 / 8, 1 / 8, None))
CORE_STEP_SHARE = 0.5  # the core's quantiser step, as a share of the error target
MAX_TENSOR_VALUES = 1 << 25  # a larger class (256 MB of float64, and HOOI's copies of it) stays PCA


@dataclass
class PredictedClip(LoadedClip):
    """A clip as the codec sees it under a tensor model: its weighted poses less `prediction`,
    which every decode it is scored by adds back, so errors are the true clip's."""

    prediction: np.ndarray | None = field(default=None, repr=False)  # (F, M) weighted poses

    @cached_property
    def poses(self) -> np.ndarray:
        return self.own_poses - self.prediction

    @property
    def own_poses(self) -> np.ndarray:
        return self.encoded.poses * self.weights

    def _decode(self, poses: np.ndarray, root: np.ndarray | None, frames):
        return super()._decode(poses + self.prediction[frames], root, frames)


def predicted(clip: LoadedClip, prediction: np.ndarray) -> PredictedClip:
    return PredictedClip(**{f.name: getattr(clip, f.name) for f in fields(LoadedClip)}, prediction=prediction)


@dataclass
class TensorClass:
    """A class coded with a tensor model: the model, each clip's levels and warping path (and its
    stored moves), and what `encode_class` made of the clips less their predictions."""

    model: TensorModel
    at: list[tuple[int, ...]]
    paths: list[np.ndarray]
    basis: object
    codings: list

    @cached_property
    def model_stream(self) -> bytes:
        """The model's `tensor/NNNN` stream, coded once: it is both measured and written."""
        return self.model.encode()

    @cached_property
    def moves(self) -> list[bytes]:
        return [encode_bytes(path_moves(path)) for path in self.paths]

    @property
    def size(self) -> int:
        return (len(self.model_stream) + sum(map(len, self.moves)) + len(self.basis.encode())
                + sum(coding.size for coding in self.codings))


def encode_tensor_class(clips: list[LoadedClip], at: list[tuple[int, ...]], transform, target: CodingTarget,
                        tried: list | None = None):
    """(basis, codings, TensorClass or None): the class coded as `encode_class` codes it, and with
    a tensor model at each of RANKS; whichever takes the fewest bytes. `at`: each clip's
    levels in the natural modes (`classes.modes.natural_modes`), a full grid. `tried`, if a list,
    receives what each coding took (benchmarks/tensor.py reports it)."""
    basis, codings = encode_class(clips, transform, target)
    best_size, best = len(basis.encode()) + sum(coding.size for coding in codings), None
    if tried is not None:
        tried.append({"model": "pca", "bytes": best_size})
    try:
        warped = _warped_tensor(clips, at)
    except ValueError:  # no warping path (`timewarp`): the class stays PCA
        warped = None
    if warped is None:
        return basis, codings, None
    paths, tensor, mean = warped
    for frames_share, values_share, natural in RANKS:
        ranks = [max(1, round(frames_share * tensor.shape[0])), max(1, round(values_share * tensor.shape[1])),
                 *(tensor.shape[2:] if natural is None else [min(natural, n) for n in tensor.shape[2:]])]
        if not _storable(tensor.shape, ranks):
            continue
        core, factors = hooi(tensor, ranks)
        model = TensorModel.quantised(mean, core, factors, CORE_STEP_SHARE * target.error_cm)
        residual = [predicted(clip, prediction(model, place, path)) for clip, place, path in zip(clips, at, paths)]
        trial = TensorClass(model, at, paths, *encode_class(residual, transform, target))
        if tried is not None:
            tried.append({"model": "tensor", "ranks": ranks, "bytes": trial.size, "model_bytes": len(trial.model_stream),
                          "path_bytes": sum(map(len, trial.moves)), "basis_bytes": len(trial.basis.encode()),
                          "clip_bytes": sum(coding.size for coding in trial.codings)})
        if _pays(trial.size, best_size):
            best_size, best = trial.size, trial
    return (basis, codings, None) if best is None else (best.basis, best.codings, best)


def _pays(tensor_bytes: int, best_bytes: int) -> bool:
    """Whether a tensor coding of `tensor_bytes` beats the best so far (tests force a model here)."""
    return tensor_bytes < best_bytes


def _storable(shape, ranks) -> bool:
    """Whether a model of these ranks is within what a reader takes (`TensorModel.decode`)."""
    try:
        check_model_sizes(list(shape), list(ranks))
    except ValueError:
        return False
    return True


def _warped_tensor(clips: list[LoadedClip], at: list[tuple[int, ...]]):
    """(each clip's warping path onto the longest clip, the tensor of warped weighted poses less
    the class's mean pose: frames x values x natural modes, the mean); None for a tensor of more
    than MAX_TENSOR_VALUES values."""
    levels = [max(place[k] for place in at) + 1 for k in range(len(at[0]))]
    longest = max(clip.motion.n_frames for clip in clips)
    if longest * clips[0].poses.shape[1] * math.prod(levels) > MAX_TENSOR_VALUES:
        return None
    features = []
    for clip in clips:
        pose = forward(clip.model, clip.motion.values, clip.layout)
        features.append(physics_features(clip.model, pose.positions, pose.rotations, clip.fps))
    reference = int(np.argmax([len(f) for f in features]))  # the longest: no clip loses frames to the warp
    paths = [multiscale_dtw(features[reference], f, clip.fps).path for f, clip in zip(features, clips)]
    mean = np.concatenate([clip.poses for clip in clips]).mean(axis=0)
    tensor = np.zeros((len(features[reference]), clips[0].poses.shape[1], *levels))
    for clip, place, path in zip(clips, at, paths):
        tensor[(slice(None), slice(None), *place)] = Warping(path, 0.0, 0).carried(clip.poses, onto=0) - mean
    return paths, tensor, mean
