"""Seed 002's experiment on our data: a class of motions as a tensor (frames x DOFs x natural
modes), reduced mode by mode, and against PCA at equal numbers of stored coefficients.

    python benchmarks/tensor.py [--data ../shared/data]
    python benchmarks/tensor.py --codec [-e 1 -e 0.5] [-j 2]

Classes, each with its natural modes from the file names:
- Bandai `walk`: 14 styles x 2 takes (BVH, 30 Hz; "normal" left out, its second take is 31 frames);
- HDM05 `jogLeftCircle4StepsRstart`: 3 actors (120 Hz);
- HDM05 `sneak2StepsLStart`: 3 actors (the first take of each).

Each clip is read as mcz codes it (the `aligned` representation, weighted poses: `inputs.clip`),
then aligned to the class's longest clip by multiscale DTW on physics features
(`motion.timewarp`), warped to its length (each reference frame: the mean of the clip's frames
matched to it) and stacked. The class mean pose is taken out, as PCA does. A model is decoded by
putting each clip back on its own timeline (each frame: the mean of the reference frames matched to
it) and through mcz's decode tail, with the root track kept exact (it is not in the tensor),
and measured end to end in two errors:
- the seed's, the mean angle between original and decoded joint rotations (degrees, every joint
  and frame);
- ours, the mean joint-position error (cm).

Printed: the error of full ranks (what warping there and back alone loses), the truncation of
each mode alone (`codec.tensor.hooi`), and tensor models next to per-class PCA (on the clips' own
timelines, no warping) by stored numbers (core + factors; basis + coefficients). Warping paths are
not counted; they are a few bytes per frame once coded.
"""

from __future__ import annotations

import argparse
import itertools
import re
from pathlib import Path

import numpy as np

from mocapzip.archive import Archive
from mocapzip.codec.tensor import hooi, reconstruct, stored_numbers
from mocapzip.ratecontrol.tensor import encode_tensor_class
from mocapzip.defaults import DEFAULT_FPS
from mocapzip.inputs.clip import ClipReader
from mocapzip.inputs.discover import find_clips
from mocapzip.motion.kinematics import forward
from mocapzip.motion.physics import physics_features
from mocapzip.motion.rotations import rotation_angle
from mocapzip.motion.timewarp import multiscale_dtw

DATA = Path(__file__).resolve().parents[2] / "shared" / "data"
CLASSES = {  # name: (glob under the data folder, natural modes: a pattern whose groups name each clip's place)
    # "normal" left out: its second take is 31 frames long, with fewer channels
    "Bandai walk": ("bvh-bandai/dataset-1_walk_*.bvh", r"walk_(?P<style>(?!normal)[a-z-]+)_(?P<take>\d+)\.bvh$"),
    "HDM05 jog": ("hdm05/*/*jogLeftCircle4StepsRstart*", r"HDM_(?P<actor>[a-z]+)_"),
    "HDM05 sneak": ("hdm05/*/*sneak2StepsLStart_00[147]*", r"HDM_(?P<actor>[a-z]+)_"),
}


class WarpedClass:
    """A class's clips, their alignment to the longest, and the tensor of their warped poses."""

    def __init__(self, paths: list[Path], pattern: str):
        paths = [path for path in paths if re.search(pattern, path.name)]
        places = [re.search(pattern, path.name).groupdict() for path in paths]
        self.modes = list(places[0])
        self.levels = {mode: sorted({place[mode] for place in places}) for mode in self.modes}
        index = {tuple(place[m] for m in self.modes): k for k, place in enumerate(places)}
        grid = list(itertools.product(*(self.levels[m] for m in self.modes)))
        if sorted(index) != sorted(grid):
            raise SystemExit(f"{paths[0].parent}: the clips do not fill the grid of {self.modes}")
        reader = ClipReader("aligned", fps=DEFAULT_FPS)  # each clip at the rate its files state (Bandai: 30 Hz)
        by_name = {source.motion.name: reader.read(source) for source in find_clips(paths)}
        self.clips = [by_name[path.name] for path in paths]
        features = [self._features(clip) for clip in self.clips]
        longest = int(np.argmax([len(f) for f in features]))  # the reference: no clip loses frames to the warp
        self.warpings = [multiscale_dtw(features[longest], f, clip.fps) for f, clip in zip(features, self.clips)]
        warped = [warping.carried(clip.poses, onto=0) for clip, warping in zip(self.clips, self.warpings)]
        self.mean = np.concatenate([clip.poses for clip in self.clips]).mean(axis=0)
        frames, width = warped[0].shape
        self.tensor = np.empty((frames, width, *(len(self.levels[m]) for m in self.modes)))
        for place, k in index.items():
            at = tuple(self.levels[m].index(level) for m, level in zip(self.modes, place))
            self.tensor[(slice(None), slice(None), *at)] = warped[k] - self.mean
        self.at = {k: tuple(self.levels[m].index(level) for m, level in zip(self.modes, place))
                   for place, k in index.items()}
        self.originals = [self._rotations(clip, clip.motion.values) for clip in self.clips]

    @staticmethod
    def _features(clip) -> np.ndarray:
        pose = forward(clip.model, clip.motion.values, clip.layout)
        return physics_features(clip.model, pose.positions, pose.rotations, clip.fps)

    @staticmethod
    def _rotations(clip, values: np.ndarray) -> np.ndarray:
        """(frames, joints, 3, 3) each joint's rotation relative to its parent's (the root's: in the world)."""
        world = forward(clip.model, values, clip.layout).rotations
        parents = clip.model.parents
        local = world.copy()
        local[:, 1:] = world[:, 1:] @ np.swapaxes(world[:, parents[1:]], -1, -2)
        return local

    def errors(self, poses_of_clip: list[np.ndarray]) -> tuple[float, float]:
        """(mean degrees, mean cm) over every clip's frames, each clip decoded from its poses, root exact."""
        degrees, cm, frames = 0.0, 0.0, 0
        for clip, poses, original in zip(self.clips, poses_of_clip, self.originals):
            check = clip.final_check(poses, clip.root)
            angles = np.degrees(rotation_angle(original, self._rotations(clip, check.values)))
            degrees += angles.mean() * len(poses)
            cm += check.error[0] * len(poses)
            frames += len(poses)
        return degrees / frames, cm / frames

    def tensor_errors(self, ranks) -> tuple[float, float]:
        model = reconstruct(*hooi(self.tensor, ranks)) if ranks != self.tensor.shape else self.tensor
        return self.errors([warping.carried(model[(slice(None), slice(None), *self.at[k])] + self.mean, onto=1)
                            for k, warping in enumerate(self.warpings)])

    def pca_errors(self, components: int) -> tuple[float, float]:
        stacked = np.concatenate([clip.poses for clip in self.clips]) - self.mean
        basis = np.linalg.svd(stacked, full_matrices=False)[2][:components].T
        return self.errors([(clip.poses - self.mean) @ basis @ basis.T + self.mean for clip in self.clips])

    def pca_stored(self, components: int) -> int:
        return components * (self.tensor.shape[1] + sum(len(clip.poses) for clip in self.clips))


def report(name: str, warped: WarpedClass) -> None:
    shape = warped.tensor.shape
    names = ["frames", "DOFs", *warped.modes]
    frames = sum(len(clip.poses) for clip in warped.clips)
    print(f"\n### {name}: {len(warped.clips)} clips, {frames} frames; tensor {' x '.join(map(str, shape))} "
          f"({' x '.join(names)})\n")
    full = warped.tensor_errors(shape)
    print(f"Full ranks (warped to {shape[0]} frames and back): {full[0]:.2f} degrees, {full[1]:.2f} cm\n")
    print("| mode truncated | rank | stored numbers | mean angle (degrees) | mean joint error (cm) |\n"
          "|---|---:|---:|---:|---:|")
    for mode, size in enumerate(shape):
        for rank in sorted({max(1, size // d) for d in (32, 16, 8, 4, 2)} | {size - 1} - {0, size}):
            ranks = tuple(rank if k == mode else n for k, n in enumerate(shape))
            degrees, cm = warped.tensor_errors(ranks)
            print(f"| {names[mode]} | {rank} | {stored_numbers(shape, ranks):,} | {degrees:.2f} | {cm:.2f} |")
    print("\nTensor against PCA by stored numbers (PCA: basis and every frame's coefficients, no warping)\n")
    print("| model | stored numbers | mean angle (degrees) | mean joint error (cm) |\n|---|---:|---:|---:|")
    rows = []
    for q in (2, 4, 8, 16, 32):
        if q <= shape[1]:
            rows.append((warped.pca_stored(q), f"PCA, {q} components", warped.pca_errors(q)))
    for time_rank, dof_rank in itertools.product((shape[0] // 16, shape[0] // 8, shape[0] // 4), (4, 8, 16, 32)):
        if dof_rank <= shape[1]:
            ranks = (time_rank, dof_rank, *shape[2:])
            rows.append((stored_numbers(shape, ranks), f"tensor, ranks {ranks}", warped.tensor_errors(ranks)))
    for stored, label, (degrees, cm) in sorted(rows):
        print(f"| {label} | {stored:,} | {degrees:.2f} | {cm:.2f} |")


# --codec: `mcz compress --model tensor` against the default. Each set's classes are its natural
# classes (an HDM05 motion, a Bandai content), split by pose width where skeletons differ (a class
# spans one width), and its modes the pattern below.
CODEC_SETS = {
    "HDM05": ("hdm05/*/*.amc", r"HDM_[a-z]+_(?P<cls>[A-Za-z0-9]+)_", r"HDM_(?P<actor>[a-z]+)_"),
    "Bandai": ("bvh-bandai/*.bvh", r"dataset-1_(?P<cls>[a-z-]+)_", r"_(?P<style>[a-z-]+)_(?P<take>[0-9]+)[.]bvh$"),
}


def codec_report(data: Path, errors: list[float], jobs: int) -> None:
    """Bytes per frame of each set with the default classes, with its natural classes, and with those
    and `--model tensor`; then, per class whose clips fill a grid, what PCA and each tensor coding took."""
    import csv
    import tempfile

    from mocapzip.archive import Settings, compress
    from mocapzip.archive.settings import checked
    from mocapzip.archive.passes import class_coding

    tried: dict[str, list] = {}

    def recording(clips, at, transform, target):
        trials = tried.setdefault(f"{len(clips)} clips, {clips[0].source.relpath}, {target.error_cm:g} cm", [])
        return encode_tensor_class(clips, at, transform, target, trials)

    class_coding.encode_tensor_class = recording
    print("| set | clips | frames | -e (cm) | default classes | natural classes | --model tensor | classes as tensors |\n"
          "|---|---:|---:|---:|---:|---:|---:|---:|")
    with tempfile.TemporaryDirectory() as tmp:
        for name, (pattern, cls, modes) in CODEC_SETS.items():
            paths = sorted(data.glob(pattern))
            table = Path(tmp) / f"{name}.csv"
            default = checked(Settings())  # the representation compress resolves at -e 1
            reader = ClipReader(default.representation, default.axis_weight_cm,
                                axes_from_positions=default.axes_from_positions, fps=DEFAULT_FPS)
            with table.open("w", newline="") as out:
                for path, source in zip(paths, find_clips(paths)):
                    width = reader.read(source).poses.shape[1]
                    csv.writer(out).writerow([source.relpath, f"{re.search(cls, path.name)['cls']}-w{width}"])
            for error in errors:
                row = []
                for options in ({}, {"classes": str(table)}, {"classes": str(table), "model": "tensor", "modes": modes}):
                    summary = compress(paths, Path(tmp) / "db.mcz", Settings(error_cm=error, **options), force=True,
                                       jobs=jobs)
                    row.append(summary)
                with Archive(Path(tmp) / "db.mcz") as archive:
                    tensors = sum(c.get("model") == "tensor" for c in archive.meta["classes"])
                print(f"| {name} | {row[0]['clips']} | {row[0]['frames']:,} | {error:g} | "
                      + " | ".join(f"{r['bytes_per_frame']:.3f}" for r in row)
                      + f" | {tensors} of {len(archive.meta['classes'])} |")
    print("\nPer class whose clips fill a grid: bytes by PCA, and by each tensor coding (model + paths + "
          "basis + clip streams)\n")
    print("| class | PCA | tensor ranks | tensor | model | paths | basis | clips |\n|---|---:|---|---:|---:|---:|---:|---:|")
    for label, trials in tried.items():
        plain = trials[0]["bytes"]
        for trial in trials[1:]:
            print(f"| {label} | {plain:,} | {tuple(trial['ranks'])} | {trial['bytes']:,} | {trial['model_bytes']:,} | "
                  f"{trial['path_bytes']:,} | {trial['basis_bytes']:,} | {trial['clip_bytes']:,} |")


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data", type=Path, default=DATA, help=f"the shared data folder (default {DATA})")
    parser.add_argument("--codec", action="store_true",
                        help="instead: bytes per frame with `mcz compress --model tensor` against the default")
    parser.add_argument("-e", type=float, action="append", help="--codec: error targets (default 1 and 0.5 cm)")
    parser.add_argument("-j", type=int, default=2, help="--codec: worker processes (default 2)")
    args = parser.parse_args(argv)
    if args.codec:
        codec_report(args.data, args.e or [1.0, 0.5], args.j)
        return 0
    for name, (pattern, modes) in CLASSES.items():
        report(name, WarpedClass(sorted(args.data.glob(pattern)), modes))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
